#include "stampscan/sim/camera_model.hpp"

#include "stampscan/acquisition/sensor_sight.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <random>

namespace stampscan::sim {

// OpenCV's model, written once: the station's own projection (acquisition/sensor_sight.hpp).
Vec2 CameraIntrinsics::project(const Vec3& c) const { return acquisition::projectPixel(record(), c); }

Vec3 CameraIntrinsics::ray(double u, double v) const {
  const double x0 = (u - cx) / fx, y0 = (v - cy) / fy;
  double x = x0, y = y0;
  for (int it = 0; it < 20; ++it) {
    const double r2 = x * x + y * y;
    const double inverse_radial = 1 / (1 + r2 * (k1 + r2 * (k2 + r2 * k3)));
    const double dx = 2 * p1 * x * y + p2 * (r2 + 2 * x * x);
    const double dy = p1 * (r2 + 2 * y * y) + 2 * p2 * x * y;
    x = (x0 - dx) * inverse_radial;
    y = (y0 - dy) * inverse_radial;
  }
  return Vec3(x, y, 1).normalized();
}

CameraIntrinsics CameraIntrinsics::scaled(double factor) const {
  CameraIntrinsics c = *this;
  c.width = std::max(1, static_cast<int>(std::lround(width * factor)));
  c.height = std::max(1, static_cast<int>(std::lround(height * factor)));
  c.fx *= factor;
  c.fy *= factor;
  c.cx = (cx + 0.5) * factor - 0.5;
  c.cy = (cy + 0.5) * factor - 0.5;
  return c;
}

std::vector<std::uint8_t> GrayImage::bytes() const {
  std::vector<std::uint8_t> out;
  if (bits == 8) {
    out.reserve(pixels.size());
    for (std::uint16_t p : pixels) out.push_back(static_cast<std::uint8_t>(p));
  } else {
    out.reserve(2 * pixels.size());
    for (std::uint16_t p : pixels) {
      out.push_back(static_cast<std::uint8_t>(p & 0xff));
      out.push_back(static_cast<std::uint8_t>(p >> 8));
    }
  }
  return out;
}

namespace {

// Separable Gaussian blur with clamped borders.
void blur(std::vector<float>& image, int width, int height, double sigma) {
  if (sigma <= 0) return;
  const int radius = static_cast<int>(std::ceil(3 * sigma));
  std::vector<float> kernel(2 * radius + 1);
  double sum = 0;
  for (int i = -radius; i <= radius; ++i) sum += kernel[i + radius] = static_cast<float>(std::exp(-0.5 * i * i / (sigma * sigma)));
  for (float& k : kernel) k = static_cast<float>(k / sum);
  std::vector<float> tmp(image.size());
  tbb::parallel_for(0, height, [&](int y) {
    const float* row = &image[static_cast<std::size_t>(y) * width];
    for (int x = 0; x < width; ++x) {
      float acc = 0;
      for (int i = -radius; i <= radius; ++i) acc += kernel[i + radius] * row[std::clamp(x + i, 0, width - 1)];
      tmp[static_cast<std::size_t>(y) * width + x] = acc;
    }
  });
  tbb::parallel_for(0, height, [&](int y) {
    for (int x = 0; x < width; ++x) {
      float acc = 0;
      for (int i = -radius; i <= radius; ++i)
        acc += kernel[i + radius] * tmp[static_cast<std::size_t>(std::clamp(y + i, 0, height - 1)) * width + x];
      image[static_cast<std::size_t>(y) * width + x] = acc;
    }
  });
}

}  // namespace

CameraRenderer::CameraRenderer(const CameraIntrinsics& intrinsics) : intrinsics_(intrinsics) {
  const int W = intrinsics.width, H = intrinsics.height;
  rays_.resize(static_cast<std::size_t>(W) * H);
  tbb::parallel_for(0, H, [&](int v) {
    for (int u = 0; u < W; ++u) rays_[static_cast<std::size_t>(v) * W + u] = intrinsics.ray(u, v).cast<float>();
  });
}

GrayImage renderImage(const Scene& scene, const CameraIntrinsics& intrinsics, const CameraSensor& sensor,
                      const Eigen::Isometry3d& machine_from_camera, std::uint64_t seed) {
  return CameraRenderer(intrinsics).render(scene, sensor, machine_from_camera, seed);
}

GrayImage CameraRenderer::render(const Scene& scene, const CameraSensor& sensor,
                                 const Eigen::Isometry3d& machine_from_camera, std::uint64_t seed) const {
  return expose(radiance(scene, sensor, machine_from_camera), sensor, seed);
}

std::vector<float> CameraRenderer::radiance(const Scene& scene, const CameraSensor& sensor,
                                            const Eigen::Isometry3d& machine_from_camera,
                                            const std::function<bool()>& cancelled) const {
  const CameraIntrinsics& in = intrinsics_;
  const int W = in.width, H = in.height;
  std::vector<float> radiance(static_cast<std::size_t>(W) * H);
  const Vec3 eye = machine_from_camera.translation();
  const Eigen::Matrix3d rotation = machine_from_camera.linear();
  const double footprint_per_mm = 1.0 / std::sqrt(in.fx * in.fy);  // one pixel's angular size
  std::atomic<bool> stop{false};
  tbb::parallel_for(0, H, [&](int v) {
    if (cancelled && (stop || (v % 16 == 0 && cancelled()))) {
      stop = true;
      return;
    }
    double t_hint = -1;
    for (int u = 0; u < W; ++u) {
      const std::size_t i = static_cast<std::size_t>(v) * W + u;
      const Vec3 dir_camera = rays_[i].cast<double>();
      const Ray ray{eye, rotation * dir_camera};
      const auto hit = scene.cast(ray, footprint_per_mm, t_hint);
      float value = 0;
      if (hit) {
        t_hint = hit->t;
        // A ring light around the lens: Lambertian, falling off with the square of the distance;
        // plus a little room light. Lens falloff (cos^4) darkens the corners.
        const double cos_light = std::max(0.0, -hit->normal.dot(ray.direction));
        const double ratio = sensor.standoff / hit->t;
        const double cos_field_sq = dir_camera.z() * dir_camera.z();
        const double light = (1 - sensor.ambient) * cos_light * ratio * ratio + sensor.ambient;
        value = static_cast<float>(hit->albedo / PartScene::kSheetAlbedo * light * cos_field_sq * cos_field_sq);
      } else {
        t_hint = -1;
      }
      radiance[i] = value;
    }
  });
  if (stop) return radiance;
  blur(radiance, W, H, sensor.blur_sigma);
  return radiance;
}

GrayImage CameraRenderer::expose(const std::vector<float>& radiance, const CameraSensor& sensor, std::uint64_t seed) const {
  const int W = intrinsics_.width, H = intrinsics_.height;
  GrayImage image;
  image.width = W;
  image.height = H;
  image.bits = sensor.bits;
  image.pixels.resize(radiance.size());
  const double max_dn = sensor.bits == 8 ? 255.0 : 4095.0;
  tbb::parallel_for(0, H, [&](int v) {
    std::mt19937_64 rng(seed * 0x9E3779B97F4A7C15ull + static_cast<std::uint64_t>(v));
    std::normal_distribution<double> gauss(0.0, 1.0);
    for (int u = 0; u < W; ++u) {
      const std::size_t i = static_cast<std::size_t>(v) * W + u;
      // Electrons collected, with shot noise (Gaussian approximation of Poisson) and read noise.
      const double electrons = std::max(0.0, radiance[i] * sensor.exposure * sensor.full_well);
      const double noisy = electrons + std::sqrt(electrons + sensor.read_noise * sensor.read_noise) * gauss(rng);
      const double dn = std::clamp(std::round(noisy / sensor.full_well * max_dn), 0.0, max_dn);
      image.pixels[i] = static_cast<std::uint16_t>(sensor.bits == 8 ? dn : dn * 16);
    }
  });
  return image;
}

}  // namespace stampscan::sim
