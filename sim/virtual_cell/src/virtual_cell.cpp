#include "stampscan/sim/virtual_cell.hpp"

#include "stampscan/drivers/plc/plc_register_map.hpp"
#include "stampscan/sim/digitizer_model.hpp"
#include "stampscan/sim/scene.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

namespace stampscan::sim {

// Everything on the table at once: the nearest hit among the part, the ball bar's two spheres and
// the plate.
class VirtualCell::WorldScene final : public Scene {
 public:
  // Owns its part: a part loaded later replaces the whole scene.
  WorldScene(std::unique_ptr<FormedPart> part, const ScanParams& p)
      : formed_(std::move(part)), part_(*formed_, p.grid, machineFromDatum(p)), sphere_(p.sphere), second_sphere_(p.second_sphere), plate_(p.plate, platePose(p)),
        has_second_sphere_(p.has_second_sphere) {}

  std::optional<Hit> cast(const Ray& ray, double footprint_per_mm, double t_hint) const override {
    std::optional<Hit> best;
    for (const Scene* s : {static_cast<const Scene*>(&part_), static_cast<const Scene*>(&sphere_),
                           static_cast<const Scene*>(&second_sphere_), static_cast<const Scene*>(&plate_)}) {
      if (s == &second_sphere_ && !has_second_sphere_) continue;
      std::optional<Hit> h = s->cast(ray, footprint_per_mm, t_hint);
      if (h && (!best || h->t < best->t)) best = h;
    }
    return best;
  }

  const FormedPart& formed() const { return *formed_; }

 private:
  std::unique_ptr<FormedPart> formed_;
  PartScene part_;
  SphereScene sphere_, second_sphere_;
  PlateScene plate_;
  bool has_second_sphere_;
};

VirtualCell::VirtualCell(VirtualCellOptions options) : options_(std::move(options)) {
  scene_.store(std::make_shared<const WorldScene>(makePart(options_.world), options_.world));
  truth_ = drawCellTruth(options_.world);

  VirtualCmmConfig cmm;
  cmm.address = options_.cmm_address;
  cmm.port = options_.cmm_port;
  if (options_.replay) {
    cmm.follow = [replay = options_.replay](const std::array<double, 6>& from, const std::array<double, 6>& to,
                                            std::chrono::steady_clock::time_point now) {
      return replay->followMove(from, to, now);
    };
  }
  cmm_ = std::make_unique<VirtualCmm>(cmm);
  VirtualPlcOptions plc;
  plc.address = options_.plc_address;
  plc.port = options_.plc_port;
  plc.unit_id = options_.plc_unit_id;
  plc.registers = options_.plc_registers;
  plc_ = std::make_unique<VirtualPlc>(plc);
  if (options_.cameras) {
    for (int c = 0; c < 2; ++c) {
      VirtualCameraOptions o;
      o.address = c == 0 ? options_.left_address : options_.right_address;
      o.serial = c == 0 ? options_.left_serial : options_.right_serial;
      const CameraIntrinsics& drawn = c == 0 ? truth_.left : truth_.right;
      o.sensor_width = drawn.width;
      o.sensor_height = drawn.height;
      cameras_.push_back(std::make_unique<VirtualCamera>(o));
      renderers_[c] = std::make_unique<CameraRenderer>(c == 0 ? truth_.left : truth_.right);
      frame_bits_[static_cast<std::size_t>(c)] = options_.world.camera_sensor.bits;
      cameras_.back()->setFrameSource([this, c](const FrameRequest& request, std::span<std::uint8_t> out) {
        return renderFrame(c, request, out);
      });
    }
  }
}

std::vector<float> VirtualCell::radianceAt(int camera, const HeadKey& key, const std::function<bool()>& cancelled) const {
  const HeadState head{Vec3(key.position[0], key.position[1], key.position[2]), key.a, key.b, 0};
  const Eigen::Isometry3d machine_from_camera = head.pose() * (camera == 0 ? truth_.head_from_left : truth_.head_from_right);
  return renderers_[camera]->radiance(*scene_.load(), options_.world.camera_sensor, machine_from_camera, cancelled);
}

bool VirtualCell::laserSweeping() const {
  return plc_->coil(drivers::plc::Coil::LaserShutterOpenRequest) &&
         !plc_->input(drivers::plc::DiscreteInput::LaserShutterClosed);
}

void VirtualCell::renderAhead() {
  std::unique_lock lock(ahead_mutex_);
  for (;;) {
    // Polled: a move's destination is known from its start, and travel takes a second or so.
    ahead_changed_.wait_for(lock, std::chrono::milliseconds(20), [&] { return ahead_stop_; });
    if (ahead_stop_) return;
    if (laserSweeping()) {
      among_views_ = false;
      continue;
    }
    if (!among_views_) continue;
    const VirtualCmmStatus st = cmm_->status();
    const HeadKey key{st.destination, st.destination_a, st.destination_b};
    if (ahead_.head == key && (ahead_.ready || ahead_.rendering)) continue;
    ahead_.head = key;
    ahead_.ready = false;
    ahead_.rendering = true;
    lock.unlock();
    // Given up when the head is sent elsewhere or the laser starts sweeping (its profiles are due
    // in real time), unless a frame of this pose waits for it, or when the cell stops.
    const auto moved_on = [&] {
      {
        std::lock_guard stop_lock(ahead_mutex_);
        if (ahead_stop_) return true;
        if (ahead_awaited_ > 0) return false;
      }
      const VirtualCmmStatus now = cmm_->status();
      return !(HeadKey{now.destination, now.destination_a, now.destination_b} == key) || laserSweeping();
    };
    std::array<std::vector<float>, 2> radiance;
    std::array<Ahead::Exposed, 2> exposed;
    bool complete = true;
    for (int c = 0; c < 2 && complete; ++c) {
      const auto k = static_cast<std::size_t>(c);
      radiance[k] = radianceAt(c, key, moved_on);
      complete = !moved_on();
      if (!complete) break;
      // The camera's next frame, at the depth it was last asked for.
      CameraSensor sensor = options_.world.camera_sensor;
      sensor.bits = frame_bits_[k].load();
      exposed[k].index = cameras_[k]->framesFilled();
      exposed[k].bits = sensor.bits;
      exposed[k].bytes = renderers_[k]->expose(radiance[k], sensor, exposureSeed(c, exposed[k].index)).bytes();
      complete = !moved_on();
    }
    lock.lock();
    ahead_.rendering = false;
    if (complete && ahead_.head == key) {
      ahead_.radiance = std::move(radiance);
      ahead_.exposed = std::move(exposed);
      ahead_.ready = true;
    }
    ahead_changed_.notify_all();
  }
}

bool VirtualCell::renderFrame(int camera, const FrameRequest& request, std::span<std::uint8_t> out) const {
  if (options_.replay) return replayFrame(camera, request, out);
  const CameraRenderer& renderer = *renderers_[camera];
  const CameraIntrinsics& in = renderer.intrinsics();
  // The image the camera is set to must be the size its optics are simulated at.
  if (static_cast<int>(request.width) != in.width || static_cast<int>(request.height) != in.height) return false;
  // The head where it stood when the exposure started (the station may have sent it on since). A
  // camera in a process of its own reads the head as it is now, which the trigger just preceded.
  const VirtualCmmStatus st = options_.head_status ? options_.head_status() : cmm_->statusAt(request.exposure);
  const HeadKey key{st.position, st.head_a, st.head_b};
  const bool at_rest = key == HeadKey{st.destination, st.destination_a, st.destination_b};
  CameraSensor sensor = options_.world.camera_sensor;
  sensor.bits = request.bytes_per_pixel == 2 ? 16 : 8;
  const auto k = static_cast<std::size_t>(camera);
  frame_bits_[k] = sensor.bits;
  among_views_ = true;
  // The frame exposed ahead for this very pose (waiting for it when it is under way), else the
  // light rendered ahead, else both now.
  std::vector<float> radiance;
  {
    std::unique_lock lock(ahead_mutex_);
    if (at_rest && ahead_.head == key) {
      ++ahead_awaited_;
      ahead_changed_.wait(lock, [&] { return !ahead_.rendering || !(ahead_.head == key); });
      --ahead_awaited_;
      if (ahead_.ready && ahead_.head == key) {
        const Ahead::Exposed& e = ahead_.exposed[k];
        if (e.index == request.index && e.bits == sensor.bits && e.bytes.size() == out.size()) {
          std::copy(e.bytes.begin(), e.bytes.end(), out.begin());
          return true;
        }
        radiance = ahead_.radiance[k];
      }
    }
  }
  if (radiance.empty()) radiance = radianceAt(camera, key);
  const std::vector<std::uint8_t> bytes = renderer.expose(radiance, sensor, exposureSeed(camera, request.index)).bytes();
  if (bytes.size() != out.size()) return false;
  std::copy(bytes.begin(), bytes.end(), out.begin());
  return true;
}

std::uint64_t VirtualCell::exposureSeed(int camera, std::uint64_t index) const {
  return options_.world.seed * 1000003ull + index * 2 + static_cast<std::uint64_t>(camera);
}

// The recorded frame of that instant; a black one when the recording has none of that size there
// (the view was missing when recorded, or the camera is set to another size).
bool VirtualCell::replayFrame(int camera, const FrameRequest& request, std::span<std::uint8_t> out) const {
  CellReplay& replay = *options_.replay;
  const RecordedFrame* frame =
      replay.frameNear(camera, replay.recordedTime(request.exposure), 2'000'000'000);
  if (frame && frame->width == request.width && frame->height == request.height &&
      frame->bytes_per_pixel == request.bytes_per_pixel && frame->data.size() == out.size()) {
    std::copy(frame->data.begin(), frame->data.end(), out.begin());
  } else {
    std::fill(out.begin(), out.end(), std::uint8_t{0});
  }
  return true;
}

VirtualCell::~VirtualCell() { stop(); }

const FormedPart& VirtualCell::part() const { return scene_.load()->formed(); }

std::shared_ptr<const FormedPart> VirtualCell::sharedPart() const {
  std::shared_ptr<const WorldScene> scene = scene_.load();
  const FormedPart* formed = &scene->formed();
  return {std::move(scene), formed};
}

std::shared_ptr<const FormedPart> VirtualCell::loadPart(const ScanParams& part_world) {
  ScanParams world = options_.world;
  world.part = part_world.part;
  world.dome = part_world.dome;
  world.pan = part_world.pan;
  world.grid = part_world.grid;
  auto scene = std::make_shared<const WorldScene>(makePart(world), world);
  scene_.store(scene);
  {
    // The light rendered ahead was of the part that went.
    std::lock_guard lock(ahead_mutex_);
    ahead_.ready = false;
    ahead_.head = HeadKey{{std::nan(""), 0, 0}, 0, 0};
  }
  ahead_changed_.notify_all();
  return {scene, &scene->formed()};
}

void VirtualCell::start() {
  if (options_.serve_cmm) cmm_->start();
  if (options_.serve_plc) plc_->start();
  for (auto& camera : cameras_) {
    const LoopbackStatus lo = VirtualCamera::ensureLoopbackAddress(camera->options().address);
    if (!lo.ok) throw std::runtime_error("virtual camera " + camera->options().serial + ": " + lo.reason);
    camera->start();
  }
  // Rendering ahead needs this object's CMM (its destination) and a world to render.
  if (!cameras_.empty() && !options_.replay && !options_.head_status && !ahead_thread_.joinable()) {
    ahead_stop_ = false;
    ahead_thread_ = std::thread([this] { renderAhead(); });
  }
}

void VirtualCell::stop() noexcept {
  {
    std::lock_guard lock(ahead_mutex_);
    ahead_stop_ = true;
  }
  ahead_changed_.notify_all();
  if (ahead_thread_.joinable()) ahead_thread_.join();
  for (auto& camera : cameras_) camera->stop();
  plc_->stop();
  cmm_->stop();
}

VirtualDigitizerOptions VirtualCell::digitizerOptions() const {
  VirtualDigitizerOptions o;
  o.paced = true;
  o.half_angle = static_cast<float>(options_.world.digitizer.half_angle);
  // A replay serves profiles stamped as they were recorded, latency included.
  o.stamp_latency_ns = options_.replay ? 0 : truth_.digitizer_latency_ns;
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
      return std::int64_t{0};
    if (options_.replay) {
      // The recorded profile nearest to this tick, stamped with its own exposure.
      CellReplay& replay = *options_.replay;
      const std::int64_t at = replay.recordedTime(exposure);
      const auto period_ns = static_cast<std::int64_t>(1e9 / std::max(config.profile_rate_hz, 1.0));
      const RecordedProfile* recorded = replay.profileNear(at, period_ns);
      if (recorded == nullptr || recorded->range.size() != n) return std::int64_t{0};
      profile.range = recorded->range;
      profile.intensity = recorded->intensity;
      profile.status = recorded->status;
      return recorded->station_time_ns - at;
    }
    const VirtualCmmStatus st = cmm_->statusAt(exposure);
    const HeadState head{Vec3(st.position[0], st.position[1], st.position[2]), st.head_a, st.head_b, 0};
    DigitizerSpec spec = options_.world.digitizer;
    spec.points_per_profile = config.points_per_profile;
    // Each profile's noise from its own stream: the same world for any timing.
    std::mt19937_64 rng(options_.world.seed * 0x9E3779B97F4A7C15ull + 0xD161ull + sequence);
    ProfileMeasurement m = measureProfile(*scene_.load(), spec, head.pose() * truth_.head_from_digitizer, rng);
    profile.range = std::move(m.range);
    profile.intensity = std::move(m.intensity);
    if (m.glare) profile.status |= 1u;  // overexposed (drivers/digitizer/PROTOCOL.md)
    return std::int64_t{0};
  };
}

}  // namespace stampscan::sim
