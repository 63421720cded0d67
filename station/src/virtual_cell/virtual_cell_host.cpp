#include "virtual_cell_host.hpp"

#include "stampscan/sim/cell_replay.hpp"
#include "stampscan/sim/grid.hpp"
#include "stampscan/sim/part_model.hpp"
#include "stampscan/sim/scan_scenario.hpp"
#include "virtual_digitizer_host.hpp"

#include <cstdio>
#include <mutex>
#include <stdexcept>

namespace stampscan::station {

namespace {

sim::PartKind partKind(const std::string& part) {
  if (part == "dome") return sim::PartKind::Dome;
  if (part == "pan") return sim::PartKind::Pan;
  throw std::invalid_argument("the virtual cell has no part '" + part + "' of its own (dome or pan)");
}

}  // namespace

std::vector<SimulatedProgramName> simulatedProgramNames() {
  std::vector<SimulatedProgramName> names;
  for (const bool sample : {false, true})
    for (const sim::PartKind part : {sim::PartKind::Dome, sim::PartKind::Pan})
      for (const sim::GridKind grid : {sim::GridKind::Circle, sim::GridKind::Square})
        names.push_back({sim::simulatedProgramName(part, grid, sample), part == sim::PartKind::Dome ? "dome" : "pan",
                         sim::toString(grid), sample, static_cast<std::uint16_t>(names.size() + 1)});
  return names;
}

std::string simulatedProgramName(const std::string& part, const std::string& grid, bool sample_region) {
  return sim::simulatedProgramName(partKind(part), sim::gridKindFromString(grid), sample_region);
}

void writeSimulatedProgram(const SimulatedProgramName& program, const acquisition::CellConfig& cell,
                           const std::filesystem::path& dir) {
  sim::SimulatedProgramOptions options;
  options.cell = &cell;
  options.sample_region = program.sample_region;
  options.line_number = program.line_number;
  sim::writeSimulatedProgram(partKind(program.part), sim::gridKindFromString(program.grid), dir, options);
}

std::shared_ptr<void> hostVirtualDigitizerOf(const acquisition::CellConfig& cell) {
  return hostVirtualDigitizer(cell);
}

// The world, the part now on the fixture (the world's own, or a program's twin), the recording a
// replay plays, and the cell once served. The panel's requests may load a program's part while the
// cell serves: the lock keeps the part and the world together.
struct VirtualCellHost::State {
  acquisition::CellConfig base;  // the cell file's, its cameras at the world's resolution
  sim::ScanParams own_world;     // with the world's own part
  sim::ScanParams world;      // with the part now on the fixture
  std::shared_ptr<sim::CellReplay> replay;
  std::unique_ptr<HostedVirtualCell> hosted;
  mutable std::mutex mutex;
};

VirtualCellHost::VirtualCellHost(const VirtualWorld& request, acquisition::CellConfig& config)
    : state_(std::make_unique<State>()) {
  sim::ScanParams world = request.quick ? sim::ScanParams::quick() : sim::ScanParams{};
  if (request.image_scale) world.image_scale = *request.image_scale;
  // The cameras the station is told of are the world's: at its image scale.
  if (world.image_scale != 1) {
    config.geometry.cameras = acquisition::atResolution(config.geometry.cameras, world.image_scale);
    world.image_scale = 1;
  }
  world.setCell(config);
  world.part = partKind(request.part);
  world.grid.kind = sim::gridKindFromString(request.grid);
  world.seed = request.options.seed;
  const std::vector<double>& shift = request.options.mount_shift;
  if (shift.size() == 3) world.digitizer_mount_shift = sim::Vec3(shift[0], shift[1], shift[2]);
  world.calibration = request.calibration_artefacts;
  state_->own_world = state_->world = world;
  state_->base = config;
}

VirtualCellHost::~VirtualCellHost() = default;

void VirtualCellHost::useProgram(const acquisition::PartProgram& program) {
  std::lock_guard lock(state_->mutex);
  state_->world = sim::worldForProgram(state_->own_world, program);
  if (state_->hosted) state_->hosted->cell().loadPart(state_->world);
}

void VirtualCellHost::useOwnPart() {
  std::lock_guard lock(state_->mutex);
  state_->world = state_->own_world;
  if (state_->hosted) state_->hosted->cell().loadPart(state_->world);
}

RecordedSession VirtualCellHost::replay(const std::string& trace, bool accept_damaged, const std::string& plan_file) {
  if (state_->hosted) throw std::logic_error("VirtualCellHost::replay after start()");
  sim::PreparedReplay prepared = sim::prepareReplay(trace, accept_damaged, plan_file);
  std::lock_guard lock(state_->mutex);
  state_->world.part = prepared.session.part == "dome" ? sim::PartKind::Dome : sim::PartKind::Pan;
  state_->own_world.part = state_->world.part;
  state_->replay = std::move(prepared.replay);
  return {std::move(prepared.plan), std::move(prepared.session)};
}

void VirtualCellHost::start(bool cameras) {
  std::lock_guard lock(state_->mutex);
  if (state_->hosted) return;
  state_->hosted = std::make_unique<HostedVirtualCell>(state_->world, state_->base, state_->replay, cameras);
}

bool VirtualCellHost::started() const { return state_->hosted != nullptr; }

const acquisition::CellConfig& VirtualCellHost::config() const {
  if (!state_->hosted) throw std::logic_error("VirtualCellHost::config before start()");
  return state_->hosted->config();
}

jobs::SimulationTruth VirtualCellHost::truthOfScan(acquisition::ScanPlan& plan) {
  std::lock_guard lock(state_->mutex);
  if (!state_->hosted) throw std::logic_error("VirtualCellHost::truthOfScan before start()");
  return state_->hosted->truthOfScan(state_->world, plan);
}

jobs::SimulationTruth VirtualCellHost::truthOfPart() {
  std::lock_guard lock(state_->mutex);
  if (!state_->hosted) throw std::logic_error("VirtualCellHost::truthOfPart before start()");
  sim::VirtualCell& cell = state_->hosted->cell();
  return jobs::SimulationTruth{sim::groundTruth(cell.part(), state_->world.grid, sim::machineFromDatum(state_->world)),
                         cell.truth().digitizer_latency_ns};
}

VirtualSensorTruth VirtualCellHost::sensorTruth() const {
  std::lock_guard lock(state_->mutex);
  if (!state_->hosted) throw std::logic_error("VirtualCellHost::sensorTruth before start()");
  const sim::CellTruth& truth = state_->hosted->cell().truth();
  return {truth.head_from_digitizer, truth.head_from_left, truth.head_from_right, truth.left.fx, truth.digitizer_latency_ns};
}

void VirtualCellHost::openDoor() {
  if (state_->hosted) state_->hosted->cell().plc().openDoor();
}

void VirtualCellHost::closeDoor() {
  if (state_->hosted) state_->hosted->cell().plc().closeDoor();
}

bool VirtualCellHost::replaying() const { return state_->replay != nullptr; }

void VirtualCellHost::printReplay(const jobs::ScanJobResult& r) const {
  if (!state_->replay) return;
  const sim::ReplayStats s = state_->replay->stats();
  std::printf("  replay      followed %zu recorded moves (%zu not in the recording), served %zu recorded profiles "
              "(%zu ticks without one), %zu frames\n",
              s.moves_followed, s.moves_not_recorded, s.profiles_served, s.profiles_missing, s.frames_served);
  if (const auto& a = r.against_recording)
    std::printf("  against     station process on the recording (%zu measurements): %zu of %zu matched, position RMS "
                "%.4f mm, thickness strain RMS %.5f\n",
                r.recording_measurements, a->matched, r.measurements, a->position_rms_mm, a->strain_rms);
}

}  // namespace stampscan::station
