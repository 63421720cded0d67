#include "stampscan/sim/virtual_cell.hpp"

#include "stampscan/drivers/plc/plc_register_map.hpp"
#include "stampscan/sim/digitizer_model.hpp"
#include "stampscan/sim/scene.hpp"

#include <random>

namespace stampscan::sim {

// Everything on the table at once: the nearest hit among the part, the sphere and the plate.
class VirtualCell::WorldScene final : public Scene {
 public:
  WorldScene(const FormedPart& part, const ScanParams& p)
      : part_(part, p.grid), sphere_(p.sphere), plate_(p.plate, platePose(p.plate)) {}

  std::optional<Hit> cast(const Ray& ray, double footprint_per_mm, double t_hint) const override {
    std::optional<Hit> best;
    for (const Scene* s : {static_cast<const Scene*>(&part_), static_cast<const Scene*>(&sphere_),
                           static_cast<const Scene*>(&plate_)}) {
      std::optional<Hit> h = s->cast(ray, footprint_per_mm, t_hint);
      if (h && (!best || h->t < best->t)) best = h;
    }
    return best;
  }

 private:
  PartScene part_;
  SphereScene sphere_;
  PlateScene plate_;
};

VirtualCell::VirtualCell(VirtualCellOptions options) : options_(std::move(options)) {
  part_ = makePart(options_.world);
  scene_ = std::make_unique<WorldScene>(*part_, options_.world);
  // The mount as built differs from its drawing by a millimetre and half a degree or so, and the
  // digitizer stamps its profiles 2-4 ms after exposure: what calibration has to find.
  std::mt19937_64 rng(options_.world.seed * 0x9E3779B97F4A7C15ull + 0xCE11ull);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  truth_.head_from_digitizer_nominal = nominalDigitizerMount();
  truth_.head_from_digitizer = truth_.head_from_digitizer_nominal;
  const Vec3 w(0.008 * g(rng), 0.008 * g(rng), 0.008 * g(rng));
  if (w.norm() > 0) truth_.head_from_digitizer.linear() = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
  truth_.head_from_digitizer.translation() += Vec3(g(rng), g(rng), g(rng));
  truth_.digitizer_latency_ns = static_cast<std::int64_t>((0.002 + 0.002 * u(rng)) * 1e9);

  VirtualCmmConfig cmm;
  cmm.address = options_.cmm_address;
  cmm.port = options_.cmm_port;
  cmm_ = std::make_unique<VirtualCmm>(cmm);
  VirtualPlcOptions plc;
  plc.address = options_.plc_address;
  plc.port = options_.plc_port;
  plc_ = std::make_unique<VirtualPlc>(plc);
}

VirtualCell::~VirtualCell() { stop(); }

void VirtualCell::start() {
  cmm_->start();
  plc_->start();
}

void VirtualCell::stop() noexcept {
  plc_->stop();
  cmm_->stop();
}

VirtualDigitizerOptions VirtualCell::digitizerOptions() const {
  VirtualDigitizerOptions o;
  o.paced = true;
  o.half_angle = static_cast<float>(options_.world.digitizer.half_angle);
  o.stamp_latency_ns = truth_.digitizer_latency_ns;
  return o;
}

VirtualDigitizer::TimedProfileSource VirtualCell::profileSource() {
  return [this](std::uint32_t sequence, const drivers::digitizer::DigitizerConfig& config,
                std::chrono::steady_clock::time_point exposure, drivers::digitizer::Profile& profile) {
    const std::size_t n = static_cast<std::size_t>(config.points_per_profile);
    profile.range.assign(n, 0.0f);
    profile.intensity.assign(n, 0);
    // The PLC's shutter: closed, the laser line never reaches the part.
    if (!plc_->coil(drivers::plc::Coil::LaserShutterOpenRequest) || plc_->input(drivers::plc::DiscreteInput::LaserShutterClosed))
      return;
    const VirtualCmmStatus st = cmm_->statusAt(exposure);
    const HeadState head{Vec3(st.position[0], st.position[1], st.position[2]), st.head_a, st.head_b, 0};
    DigitizerSpec spec = options_.world.digitizer;
    spec.points_per_profile = config.points_per_profile;
    // Each profile's noise from its own stream: the same world for any timing.
    std::mt19937_64 rng(options_.world.seed * 0x9E3779B97F4A7C15ull + 0xD161ull + sequence);
    ProfileMeasurement m = measureProfile(*scene_, spec, head.pose() * truth_.head_from_digitizer, rng);
    profile.range = std::move(m.range);
    profile.intensity = std::move(m.intensity);
    if (m.glare) profile.status |= 1u;  // overexposed (drivers/digitizer/PROTOCOL.md)
  };
}

}  // namespace stampscan::sim
