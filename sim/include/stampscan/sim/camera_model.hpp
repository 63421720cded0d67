// A machine-vision camera: pinhole projection with OpenCV's lens distortion model (k1, k2, p1, p2,
// k3), and a renderer that images a scene as the sensor would: box-filtered albedo under a ring
// light, lens falloff, optical blur, shot and read noise, quantised to 8 or 16 bits.
//
// Camera frame as in OpenCV: x right, y down, z along the optical axis.
#pragma once

#include "stampscan/acquisition/trace/session_description.hpp"
#include "stampscan/sim/scene.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <functional>
#include <vector>

namespace stampscan::sim {

struct CameraIntrinsics {
  int width = 2048, height = 1536;
  double fx = 4638, fy = 4638;       // px: a 16 mm lens on 3.45 um pixels
  double cx = 1023.5, cy = 767.5;    // px
  double k1 = -0.08, k2 = 0.12, p1 = 0, p2 = 0, k3 = 0;

  // Pixel coordinates of a point in the camera frame (z > 0), distortion applied.
  Vec2 project(const Vec3& camera_point) const;
  // The unit ray through pixel (u, v), distortion removed (OpenCV's fixed-point iteration).
  Vec3 ray(double u, double v) const;
  // Scales resolution and focal length together (a smaller sensor with the same field of view).
  CameraIntrinsics scaled(double factor) const;
  // As the trace's session description records intrinsics.
  trace::CameraIntrinsicsRecord record() const { return {width, height, fx, fy, cx, cy, k1, k2, p1, p2, k3}; }
};

struct CameraSensor {
  int bits = 8;                 // 8 (mono8) or 16 (mono16: a 12-bit ADC in the high bits)
  double full_well = 10000;     // electrons at full scale
  double read_noise = 4;        // electrons
  double exposure = 0.85;       // fraction of full scale for a white diffuse surface at the nominal standoff
  double blur_sigma = 0.7;      // px, optics and focus
  double standoff = 300;        // mm where the ring light gives `exposure`
  double ambient = 0.12;        // share of uniform room light
};

struct GrayImage {
  int width = 0, height = 0;
  int bits = 8;
  std::vector<std::uint16_t> pixels;  // row-major
  std::uint16_t at(int x, int y) const { return pixels[static_cast<std::size_t>(y) * width + x]; }
  // Bytes as the camera sends them: mono8, or mono16 little endian.
  std::vector<std::uint8_t> bytes() const;
};

// Renders scenes seen by one camera. Deterministic for a given seed, whatever the number of
// threads (each row draws its noise from its own stream). The undistorted ray of every pixel is
// computed once, when the renderer is made.
class CameraRenderer {
 public:
  explicit CameraRenderer(const CameraIntrinsics& intrinsics);
  GrayImage render(const Scene& scene, const CameraSensor& sensor, const Eigen::Isometry3d& machine_from_camera,
                   std::uint64_t seed) const;
  // render() in its two stages: the light on each pixel (the scene's radiance through the optics,
  // blurred; all the ray casting, and the same for every frame taken from one pose), then the
  // sensor's exposure of it (noise drawn from `seed`, quantised). A simulated camera that stands
  // still can do the first once, before its trigger. `cancelled`, when given, is asked now and then
  // while casting: once it says yes the radiance is left incomplete (and must not be used).
  std::vector<float> radiance(const Scene& scene, const CameraSensor& sensor, const Eigen::Isometry3d& machine_from_camera,
                              const std::function<bool()>& cancelled = {}) const;
  GrayImage expose(const std::vector<float>& radiance, const CameraSensor& sensor, std::uint64_t seed) const;
  const CameraIntrinsics& intrinsics() const { return intrinsics_; }

 private:
  CameraIntrinsics intrinsics_;
  std::vector<Eigen::Vector3f> rays_;  // unit, camera frame, row-major
};

// One image with a renderer made for it.
GrayImage renderImage(const Scene& scene, const CameraIntrinsics& intrinsics, const CameraSensor& sensor,
                      const Eigen::Isometry3d& machine_from_camera, std::uint64_t seed);

}  // namespace stampscan::sim
