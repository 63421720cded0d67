// Fitting benchmark: StampScan's default fit against PCL's MovingLeastSquares (polynomial order 2,
// same thread count) on the same synthetic scan of the sample pan: laser-like overlapping strips,
// stereo-like clusters of 1-12 near-duplicates, 0.05 mm noise, a hole, a few outliers.
//
// Each system runs in a child process so that its peak memory is its own: after the cloud is made,
// the child resets its peak-RSS counter (/proc/self/clear_refs) and reports the peak during the fit.
//
//   bench_fit [--shape pan|dome] [--points N] [--threads T] [--radii r1,r2,...] [--seed S] [--skip-pcl] [--stages]
//             [--station PATH]
//
// --station PATH also times the whole `station fit` process on the same cloud, written as a binary
// PLY before the clock starts: reading the file, the fit, writing the surface (what a user runs).
//
// The pan has tight radii and steep walls; the dome is smooth all over, where wide supports pay.
#include "stampscan/fitting/ply_io.hpp"
#include "stampscan/fitting/surface_fit.hpp"
#include "stampscan/sim/sample_cloud.hpp"

#include <tbb/global_control.h>

#ifdef STAMPSCAN_HAVE_PCL
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>
#include <pcl/surface/mls.h>
#endif

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

using namespace stampscan;

namespace {
struct Result {
  double seconds = 0;
  double rms = 0;
  double max = 0;
  double peak_mb = 0;    // peak RSS during the fit above the RSS before it
  double total_mb = 0;   // peak RSS of the process during the fit
  std::size_t points = 0;
  double strain_rms = 0;  // the fitted thickness strain against the true one (StampScan only)
};

long statusKb(const char* field) {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind(field, 0) == 0) return std::atol(line.c_str() + std::strlen(field));
  return 0;
}

void resetPeak() {
  std::ofstream out("/proc/self/clear_refs");
  out << "5";
}

// Runs `fn` in a child process and returns what it wrote back through a pipe.
template <class Fn>
Result inChild(Fn&& fn) {
  int fds[2];
  if (pipe(fds) != 0) std::abort();
  const pid_t pid = fork();
  if (pid == 0) {
    close(fds[0]);
    Result r = fn();
    if (write(fds[1], &r, sizeof r) != static_cast<ssize_t>(sizeof r)) _exit(1);
    _exit(0);
  }
  close(fds[1]);
  Result r;
  if (read(fds[0], &r, sizeof r) != static_cast<ssize_t>(sizeof r)) r.seconds = -1;
  close(fds[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  return r;
}

double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

// Runs `station fit IN -o OUT --threads T -q` as its own process; its wall time and peak RSS.
Result stationFitProcess(const std::string& station, const std::filesystem::path& in, const std::filesystem::path& out,
                         int threads) {
  const std::string thread_arg = std::to_string(threads);
  const double t0 = now();
  const pid_t pid = fork();
  if (pid == 0) {
    execl(station.c_str(), station.c_str(), "fit", in.c_str(), "-o", out.c_str(), "--threads", thread_arg.c_str(), "-q",
          static_cast<char*>(nullptr));
    std::perror(station.c_str());
    _exit(127);
  }
  int status = 0;
  rusage usage{};
  wait4(pid, &status, 0, &usage);
  Result r;
  r.seconds = now() - t0;
  r.total_mb = static_cast<double>(usage.ru_maxrss) / 1024.0;
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) r.seconds = -1;
  return r;
}
}  // namespace

int main(int argc, char** argv) {
  std::size_t points = 500000;
  int threads = 2;
  std::uint64_t seed = 1;
  bool skip_pcl = false;
  bool per_point = false;
  std::vector<double> radii = {0.75, 1.0, 1.5, 2.0, 3.0};
  std::string shape_name = "pan";
  bool stages = false;  // print the fit's time per stage
  std::string station;  // the `station` program, to time `station fit` as a whole process
  fitting::AnchoredParams anchored;  // the default's parameters; --widen and --gamma change them
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto next = [&]() { return std::string(i + 1 < argc ? argv[++i] : ""); };
    if (a == "--points") points = std::stoul(next());
    else if (a == "--threads") threads = std::stoi(next());
    else if (a == "--seed") seed = std::stoull(next());
    else if (a == "--skip-pcl") skip_pcl = true;
    else if (a == "--shape") shape_name = next();
    else if (a == "--widen") anchored.widen = true;
    else if (a == "--stages") stages = true;
    else if (a == "--gamma") anchored.agreement_sigmas = std::stod(next());
    else if (a == "--blend-radius") anchored.blend_radius = std::stod(next());
    else if (a == "--tolerance") anchored.tolerance = std::stod(next());
    else if (a == "--per-point") per_point = true;
    else if (a == "--station") station = next();
    else if (a == "--radii") {
      radii.clear();
      std::stringstream ss(next());
      std::string item;
      while (std::getline(ss, item, ',')) radii.push_back(std::stod(item));
    } else {
      std::fprintf(stderr, "usage: bench_fit [--shape pan|dome] [--widen] [--gamma G] [--blend-radius R] [--tolerance T] [--points N] [--threads T] [--radii a,b,c] [--seed S] [--skip-pcl] [--stages] [--station PATH]\n");
      return 2;
    }
  }
  const sim::PanPart pan;
  const sim::DomePart dome;
  if (shape_name != "pan" && shape_name != "dome") {
    std::fprintf(stderr, "bench_fit: --shape must be pan or dome, not '%s'\n", shape_name.c_str());
    return 2;
  }
  const sim::SampleShape part = shape_name == "pan" ? sim::sampleShape(pan) : sim::sampleShape(dome);
  sim::SampleCloudParams sp;
  sp.target_points = points;
  sp.seed = seed;
  const sim::SampleCloud sample = sim::makeSampleCloud(part, sp);
  const std::size_t n = sample.cloud.size();
  // TBB's worker threads do not survive fork(): nothing parallel may run here before the children.
  std::printf("cloud: %s, %zu points (%zu laser, %zu stereo, %zu outliers), %d threads\n", shape_name.c_str(), n, sample.laser_points,
              sample.stereo_points, sample.outliers, threads);
  std::printf("%-26s %9s %10s %10s %9s %12s %12s\n", "system", "time s", "points/s", "RMS mm", "max mm", "fit B/point",
              "total B/pt");

  const auto print = [&](const std::string& name, const Result& r) {
    std::printf("%-26s %9.3f %10.0f %10.5f %9.3f %12.1f %12.1f\n", name.c_str(), r.seconds,
                static_cast<double>(r.points) / r.seconds, r.rms, r.max, r.peak_mb * 1048576.0 / static_cast<double>(n),
                r.total_mb * 1048576.0 / static_cast<double>(n));
    std::fflush(stdout);
  };

  const auto limitThreads = [&]() {
    return tbb::global_control(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads));
  };
  const Result raw = inChild([&]() {
    Result r;
    const sim::SurfaceError e = sim::surfaceError(part, sample.cloud.positions);
    r.rms = e.rms;
    r.max = e.max;
    r.points = n;
    r.seconds = 1;
    return r;
  });
  std::printf("raw scan: RMS %.4f mm, max %.3f mm from the true surface\n", raw.rms, raw.max);
  const auto runOurs = [&](fitting::FitMethod method) {
    return inChild([&, method]() {
    Result r;
    auto limit = limitThreads();
    fitting::FitParams params;
    params.method = method;
    params.anchored = anchored;
    const long before = statusKb("VmRSS:");
    resetPeak();
    const double t0 = now();
    const fitting::FitResult fit = fitting::fitSurface(sample.cloud, params);
    r.seconds = now() - t0;
    const long peak = statusKb("VmHWM:");
    r.peak_mb = static_cast<double>(peak - before) / 1024.0;
    r.total_mb = static_cast<double>(peak) / 1024.0;
    const sim::SurfaceError e = sim::surfaceError(part, fit.surface.positions);
    r.rms = e.rms;
    r.max = e.max;
    r.points = fit.surface.size();
    double strain_sq = 0;
    for (std::size_t i = 0; i < fit.surface.strain.size(); ++i) {
      const double d = fit.surface.strain[i] - sample.true_strain[i];
      strain_sq += d * d;
    }
    r.strain_rms = fit.surface.strain.empty() ? 0.0 : std::sqrt(strain_sq / static_cast<double>(fit.surface.strain.size()));
    if (stages) {
      std::string line = "  stages:";
      for (const auto& [stage, seconds] : fit.stats.stage_seconds) line += " " + stage + " " + std::to_string(seconds).substr(0, 5) + " s,";
      std::printf("%s\n  anchors %zu, probes %zu, mean iterations %.2f, not converged %zu\n", line.c_str(), fit.stats.anchors,
                  fit.stats.probes, fit.stats.mean_iterations, fit.stats.not_converged);
      std::fflush(stdout);
    }
    return r;
    });
  };
  const Result ours = runOurs(fitting::FitMethod::Auto);
  print("stampscan auto (default)", ours);
  {
    double raw_sq = 0;
    for (std::size_t i = 0; i < sample.cloud.strain.size(); ++i)
      raw_sq += (sample.cloud.strain[i] - sample.true_strain[i]) * (sample.cloud.strain[i] - sample.true_strain[i]);
    std::printf("  thickness strain RMS: raw %.5f, fitted %.5f\n", std::sqrt(raw_sq / static_cast<double>(n)), ours.strain_rms);
  }
  if (per_point) print("stampscan apss (per point)", runOurs(fitting::FitMethod::Apss));
  Result process;  // `station fit` as a whole process, with --station
  if (!station.empty()) {
    const std::filesystem::path folder = std::filesystem::temp_directory_path() / ("bench_fit_" + std::to_string(getpid()));
    std::filesystem::create_directories(folder);
    const std::filesystem::path in = folder / "cloud.ply", out = folder / "fitted.ply";
    fitting::writePly(in, sample.cloud);
    process = stationFitProcess(station, in, out, threads);
    if (process.seconds < 0) {
      std::fprintf(stderr, "bench_fit: %s fit %s failed\n", station.c_str(), in.c_str());
      return 1;
    }
    // Scored in a child: the parent runs nothing parallel before PCL's children.
    const Result scored = inChild([&]() {
      Result r;
      const fitting::Cloud fitted = fitting::readPly(out);
      const sim::SurfaceError e = sim::surfaceError(part, fitted.positions);
      r.rms = e.rms;
      r.max = e.max;
      r.points = fitted.size();
      return r;
    });
    process.rms = scored.rms;
    process.max = scored.max;
    process.points = scored.points;
    std::printf("%-26s %9.3f %10.0f %10.5f %9.3f %12s %12.1f\n", "station fit (process)", process.seconds,
                static_cast<double>(process.points) / process.seconds, process.rms, process.max, "-",
                process.total_mb * 1048576.0 / static_cast<double>(n));
    std::printf("  binary PLY in and out (%.1f MB in); the process's peak memory is its whole\n",
                static_cast<double>(std::filesystem::file_size(in)) / 1e6);
    std::fflush(stdout);
    if (!std::getenv("BENCH_FIT_KEEP")) std::filesystem::remove_all(folder);
  }

#ifdef STAMPSCAN_HAVE_PCL
  if (!skip_pcl) {
    double best_rms = 1e9, best_time = 0, best_radius = 0;
    double at_three = 0;  // PCL's time at r = 3 mm, the yardstick of the throughput goal
    for (double radius : radii) {
      const Result r = inChild([&]() {
        Result res;
        auto limit = limitThreads();
        pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
        cloud->reserve(n);
        for (const auto& p : sample.cloud.positions)
          cloud->push_back(pcl::PointXYZ(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())));
        const long before = statusKb("VmRSS:");
        resetPeak();
        const double t0 = now();
        pcl::MovingLeastSquares<pcl::PointXYZ, pcl::PointNormal> mls;
        mls.setInputCloud(cloud);
        mls.setSearchMethod(pcl::search::KdTree<pcl::PointXYZ>::Ptr(new pcl::search::KdTree<pcl::PointXYZ>));
        mls.setPolynomialOrder(2);
        mls.setSearchRadius(radius);
        mls.setComputeNormals(true);
        mls.setNumberOfThreads(static_cast<unsigned>(threads));
        pcl::PointCloud<pcl::PointNormal> out;
        mls.process(out);
        res.seconds = now() - t0;
        const long peak = statusKb("VmHWM:");
        res.peak_mb = static_cast<double>(peak - before) / 1024.0;
        res.total_mb = static_cast<double>(peak) / 1024.0;
        std::vector<fitting::Vec3> pts;
        pts.reserve(out.size());
        for (const auto& p : out.points) pts.emplace_back(p.x, p.y, p.z);
        const sim::SurfaceError e = sim::surfaceError(part, pts);
        res.rms = e.rms;
        res.max = e.max;
        res.points = out.size();
        return res;
      });
      char name[64];
      std::snprintf(name, sizeof name, "pcl mls order 2, r=%.2f", radius);
      print(name, r);
      if (r.points > 0 && radius == 3.0) at_three = r.seconds;
      if (r.points > 0 && r.rms < best_rms) {
        best_rms = r.rms;
        best_time = r.seconds;
        best_radius = radius;
      }
    }
    std::printf("\nPCL best radius %.2f mm: RMS %.4f mm in %.3f s. StampScan: RMS %.4f mm (%.2fx lower), %.1fx the throughput\n",
                best_radius, best_rms, best_time, ours.rms, best_rms / ours.rms, best_time / ours.seconds);
    if (at_three > 0) std::printf("Against PCL at r = 3 mm: %.1fx the throughput\n", at_three / ours.seconds);
    if (at_three > 0 && process.seconds > 0)
      std::printf("The whole `station fit` process against PCL's fit alone at r = 3 mm: %.1fx; against PCL's best radius %.1fx\n",
                  at_three / process.seconds, best_time / process.seconds);
  }
#endif
  return 0;
}
