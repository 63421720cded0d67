// `station process TRACE.mcap -o CLOUD4D.ply`: the measuring path on a recorded or simulated trace.
// Calibrates from the trace's calibration scenes when it has them (reference-sphere sweeps for the
// digitizer, plate views for the cameras), otherwise reads --calibration DIR; places every laser
// profile in the machine frame, finds the printed circles in each sweep's intensity, and writes the
// grid elements with their strains as a Cloud4D PLY. With --fit it also fits the surface.
#include "stampscan/fitting/ply_io.hpp"
#include "stampscan/registration/digitizer_calibration.hpp"
#include "stampscan/registration/icp.hpp"
#include "stampscan/registration/laser_rings.hpp"
#include "stampscan/registration/stereo_rings.hpp"
#include "stampscan/registration/stereo_squares.hpp"
#include "stampscan/station/calibration_files.hpp"
#include "stampscan/station/commands.hpp"
#include "stampscan/station/fit_runner.hpp"
#include "stampscan/station/progress.hpp"
#include "stampscan/station/scan_trace.hpp"

#include <tbb/parallel_for.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>

namespace stampscan::station {

namespace fs = std::filesystem;

namespace {

struct ProcessOptions {
  std::string input, output, fit, calibration_dir, save_calibration;
  bool ascii = false, quiet = false, with_stereo = false;
};

class StageClock {
 public:
  double lap() {
    const auto now = std::chrono::steady_clock::now();
    const double s = std::chrono::duration<double>(now - last_).count();
    last_ = now;
    return s;
  }
  double total() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count(); }

 private:
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now(), last_ = start_;
};

void checkFolder(const std::string& file, const char* what) {
  if (file.empty()) return;
  const fs::path parent = fs::absolute(file).parent_path();
  if (!fs::is_directory(parent)) throw std::runtime_error(std::string(what) + " folder '" + parent.string() + "' does not exist");
}

Eigen::Isometry3d poseFromCell(const ScanTrace& t, const std::string& key) {
  const std::vector<double> v = cellNumbers(t, key, 12);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) T.linear()(r, c) = v[static_cast<std::size_t>(4 * r + c)];
    T.translation()(r) = v[static_cast<std::size_t>(4 * r + 3)];
  }
  return T;
}

std::vector<registration::Profile> profilesIn(const ScanTrace& t, const SweepWindow& w, std::int64_t clock_offset,
                                              std::int64_t latency) {
  std::vector<registration::Profile> out;
  for (const auto& p : t.profiles) {
    const std::int64_t exposure = p.device_time_ns - clock_offset - latency;
    if (exposure >= w.begin_ns && exposure <= w.end_ns) out.push_back(p);
  }
  return out;
}

}  // namespace

CommandRunner addProcessCommand(CLI::App& app) {
  auto opt = std::make_shared<ProcessOptions>();
  CLI::App* cmd = app.add_subcommand("process", "Measure a scan trace: calibration, laser profiles to the machine "
                                                "frame, printed circles, strains; writes a Cloud4D PLY");
  cmd->add_option("trace", opt->input, "Recorded or simulated trace (.mcap)")->required();
  cmd->add_option("-o,--output", opt->output, "Cloud4D PLY of the grid elements")->required();
  cmd->add_option("--fit", opt->fit, "Also fit the surface (default method) and write it with strain");
  cmd->add_option("--calibration", opt->calibration_dir,
                  "Folder with digitizer.json (and cameras.json), used when the trace has no calibration scenes");
  cmd->add_option("--save-calibration", opt->save_calibration, "Write the calibrations made from the trace to this folder");
  cmd->add_flag("--with-stereo", opt->with_stereo,
                "Also measure the stereo views (matched on the laser's surface, registered to it by ICP); "
                "their strain is not yet as accurate as the laser's");
  cmd->add_flag("--ascii", opt->ascii, "Write ASCII PLY");
  cmd->add_flag("-q,--quiet", opt->quiet, "No progress bar");
  return [opt]() {
    checkFolder(opt->output, "output");
    checkFolder(opt->fit, "fit output");
    if (!opt->save_calibration.empty() && !fs::is_directory(opt->save_calibration))
      throw std::runtime_error("calibration folder '" + opt->save_calibration + "' does not exist");
    StageClock clock;
    std::printf("station process: %s\n", opt->input.c_str());

    // 1. Read the trace.
    ScanTrace trace;
    {
      ProgressBar bar;
      trace = loadScanTrace(
          opt->input,
          [&](double f) {
            if (!opt->quiet) bar.update("reading", f);
          },
          opt->with_stereo);
    }
    const double t_read = clock.lap();
    std::printf("  trace       %llu messages, %zu profiles, %zu plate frame pairs, %zu part frames; scan %.1f s (%.2f s)\n",
                static_cast<unsigned long long>(trace.health.messages_delivered), trace.profiles.size(),
                trace.plate_left.size(), trace.part_frames, trace.scan_seconds, t_read);
    if (!trace.health.healthy()) {
      if (trace.health.truncated)
        std::printf("  warning     the trace is cut at byte %llu; every complete message before it is used\n",
                    static_cast<unsigned long long>(trace.health.truncated->file_size));
      for (const auto& d : trace.health.damage)
        std::printf("  warning     damage at byte %llu: %s\n", static_cast<unsigned long long>(d.offset), d.what.c_str());
    }
    if (trace.cell.empty()) throw std::runtime_error(opt->input + ": the trace has no cell description (metadata 'cell')");
    const auto pairs = trace.clock_pairs.find("digitizer");
    if (pairs == trace.clock_pairs.end()) throw std::runtime_error(opt->input + ": no clock-sync pairs for the digitizer");
    const std::int64_t digitizer_offset = registration::clockOffset(pairs->second);
    const registration::HeadTrack track(trace.head);

    // 2. The digitizer's calibration: from the sphere sweeps, or from the calibration folder.
    registration::DigitizerCalibration digitizer;
    std::vector<registration::Profile> sphere;
    for (const auto& w : trace.sweeps)
      if (w.is("reference_sphere")) {
        auto p = profilesIn(trace, w, digitizer_offset, 0);
        sphere.insert(sphere.end(), p.begin(), p.end());
      }
    if (!sphere.empty()) {
      registration::SphereCalibrationParams params;
      params.sphere_radius = cellNumbers(trace, "reference_sphere_radius_mm", 1)[0];
      params.nominal.head_from_digitizer = poseFromCell(trace, "head_from_digitizer_nominal");
      params.nominal.clock_offset_ns = digitizer_offset;
      const registration::SphereCalibrationResult r = registration::calibrateDigitizer(sphere, track, params);
      digitizer = r.calibration;
      std::printf("  digitizer   calibrated on the reference sphere: latency %.3f ms, residual %.4f mm RMS over %zu points "
                  "(%.2f s)\n",
                  static_cast<double>(r.calibration.latency_ns) * 1e-6, r.rms_mm, r.inliers, clock.lap());
      if (!opt->save_calibration.empty()) {
        DigitizerCalibrationFile file{r.calibration, r.rms_mm, r.inliers, utcNow(), opt->input + " (reference-sphere sweeps)"};
        saveDigitizerCalibration(fs::path(opt->save_calibration) / "digitizer.json", file);
      }
    } else {
      if (opt->calibration_dir.empty())
        throw std::runtime_error(opt->input + " has no reference-sphere sweeps to calibrate the digitizer: pass "
                                              "--calibration DIR with a digitizer.json");
      const fs::path file = fs::path(opt->calibration_dir) / "digitizer.json";
      if (!fs::exists(file))
        throw std::runtime_error(opt->input + " has no reference-sphere sweeps and " + file.string() + " does not exist");
      const DigitizerCalibrationFile loaded = loadDigitizerCalibration(file);
      digitizer = loaded.calibration;
      std::printf("  digitizer   calibration from %s (made %s)\n", file.c_str(), loaded.created.c_str());
    }
    digitizer.clock_offset_ns = digitizer_offset;

    // 3. The cameras, when the trace shows the plate.
    std::optional<registration::StereoRig> rig;
    std::int64_t camera_offset = 0;
    if (trace.plate_left.size() >= 5) {
      const std::vector<double> plate = cellNumbers(trace, "camera_plate_spec", 3);
      registration::CirclePlateSpec spec{static_cast<int>(plate[0]), static_cast<int>(plate[1]), plate[2]};
      std::vector<cv::Mat> left, right;
      for (std::size_t i = 0; i < trace.plate_left.size(); ++i) {
        left.push_back(trace.plate_left[i].image);
        right.push_back(trace.plate_right[i].image);
      }
      const registration::StereoCalibration stereo = registration::calibrateStereo(left, right, spec);
      const auto camera_pairs = trace.clock_pairs.find("camera_left");
      std::vector<Eigen::Isometry3d> heads, plates;
      if (camera_pairs != trace.clock_pairs.end()) {
        const std::int64_t offset = registration::clockOffset(camera_pairs->second);
        camera_offset = offset;
        for (std::size_t v = 0; v < left.size(); ++v) {
          const std::int64_t t = trace.plate_left[v].device_time_ns - offset;
          if (stereo.left.plate_poses[v] && track.covers(t)) {
            heads.push_back(track.poseAt(t));
            plates.push_back(*stereo.left.plate_poses[v]);
          }
        }
      }
      std::printf("  cameras     calibrated on %zu plate views: reprojection %.3f / %.3f px, baseline %.3f mm",
                  stereo.pairs_used, stereo.left.rms_px, stereo.right.rms_px, stereo.baseline_mm);
      registration::HandEyeResult hand_eye;
      if (heads.size() >= 3) {
        hand_eye = registration::calibrateHeadToCamera(heads, plates);
        std::printf(", head mount residual %.3f mm", hand_eye.residual_mm);
        rig = registration::StereoRig{stereo.left.model, stereo.right.model, hand_eye.head_from_camera, stereo.right_from_left};
      }
      std::printf(" (%.2f s)\n", clock.lap());
      if (!opt->save_calibration.empty())
        saveCameraCalibration(fs::path(opt->save_calibration) / "cameras.json",
                              {stereo, hand_eye, utcNow(), opt->input + " (calibration-plate views)"});
    }

    // 4. The laser path: rings (or square cells) in every part sweep.
    const std::string grid = trace.cell.count("grid") ? trace.cell.at("grid") : "circle";
    if (grid != "circle" && grid != "square")
      throw std::runtime_error("the trace's grid is '" + grid + "': expected circle or square");
    registration::RingDetectionParams rings;
    registration::SquareDetectionParams squares;
    if (trace.cell.count("grid_circle_diameter_mm")) rings.printed_radius = 0.5 * cellNumbers(trace, "grid_circle_diameter_mm", 1)[0];
    if (trace.cell.count("grid_pitch_mm")) squares.pitch = cellNumbers(trace, "grid_pitch_mm", 1)[0];
    if (trace.cell.count("grid_line_width_mm")) rings.line_width = squares.line_width = cellNumbers(trace, "grid_line_width_mm", 1)[0];
    std::vector<SweepWindow> part;
    for (const auto& w : trace.sweeps)
      if (w.is("part")) part.push_back(w);
    std::vector<std::vector<registration::GridElement>> per_sweep(part.size());
    std::vector<registration::RingDetectionStats> stats(part.size());
    tbb::parallel_for(std::size_t{0}, part.size(), [&](std::size_t k) {
      const auto profiles = profilesIn(trace, part[k], digitizer.clock_offset_ns, digitizer.latency_ns);
      const auto id = static_cast<std::uint32_t>(k);
      per_sweep[k] = grid == "circle" ? registration::detectLaserRings(profiles, track, digitizer, rings, id, &stats[k])
                                      : registration::detectLaserSquares(profiles, track, digitizer, squares, id, &stats[k]);
    });
    std::vector<registration::GridElement> elements;
    registration::RingDetectionStats total;
    for (std::size_t k = 0; k < part.size(); ++k) {
      elements.insert(elements.end(), per_sweep[k].begin(), per_sweep[k].end());
      total.candidates += stats[k].candidates;
      total.rejected_gap += stats[k].rejected_gap;
      total.rejected_fit += stats[k].rejected_fit;
    }
    std::printf("  laser       %zu sweeps, %s grid: %zu grid elements (%zu incomplete and %zu poor fits left out) (%.2f s)\n",
                part.size(), grid.c_str(), elements.size(), total.rejected_gap, total.rejected_fit, clock.lap());
    if (elements.empty()) throw std::runtime_error(opt->input + ": no grid element was found in the laser sweeps");

    // 4b. The stereo views: rings matched on the laser's surface, each view's pose refined by ICP of
    // its triangulated rings against the laser's (known pose first, then point-to-plane ICP).
    if (opt->with_stereo) {
      if (!rig) throw std::runtime_error("--with-stereo needs the cameras calibrated: the trace has no plate views");
      std::vector<registration::Vec3> laser_positions, laser_normals;
      for (const auto& g : elements) {
        laser_positions.push_back(g.position);
        laser_normals.push_back(g.normal);
      }
      const registration::PointToPlaneIcp icp(laser_positions, laser_normals);
      std::size_t stereo_count = 0;
      double worst_correction = 0;
      for (std::size_t v = 0; v < trace.part_left.size(); ++v) {
        const std::int64_t t = trace.part_left[v].device_time_ns - camera_offset;
        if (!track.covers(t)) continue;
        const auto view_id = static_cast<std::uint32_t>(1000 + v);
        auto view = grid == "circle"
                        ? registration::measureStereoPair(trace.part_left[v].image, trace.part_right[v].image, *rig,
                                                          track.poseAt(t), laser_positions, rings, view_id)
                        : registration::measureStereoSquares(trace.part_left[v].image, trace.part_right[v].image, *rig,
                                                             track.poseAt(t), laser_positions, squares, view_id);
        if (view.size() < 10) continue;
        std::vector<registration::Vec3> source;
        for (const auto& g : view) source.push_back(g.position);
        registration::IcpParams ip;
        ip.max_correspondence_distance = 1.0;
        // Stereo and laser measure the same grid elements: each pairs with its own, so the offset
        // along the sheet counts as much as across it. Point-to-plane alone let errors across the
        // sheet on the radii slide a view sideways along the walls (0.064 mm position RMS on a
        // full square-grid pan session, 0.039 with this).
        ip.tangential_weight = 1.0;
        const registration::IcpResult fit = icp.align(source, Eigen::Isometry3d::Identity(), ip);
        if (fit.converged && fit.fitness > 0.5) {
          worst_correction = std::max(worst_correction, fit.transform.translation().norm());
          for (auto& g : view) {
            g.position = fit.transform * g.position;
            g.normal = fit.transform.linear() * g.normal;
            g.major_direction = fit.transform.linear() * g.major_direction;
          }
        }
        stereo_count += view.size();
        elements.insert(elements.end(), view.begin(), view.end());
      }
      std::printf("  stereo      %zu views: %zu grid elements, ICP corrections up to %.3f mm (%.2f s)\n",
                  trace.part_left.size(), stereo_count, worst_correction, clock.lap());
      if (stereo_count == 0 && !trace.part_left.empty()) {
        // Say why when it is the images' scale: the line's centre needs the line to span pixels.
        const std::int64_t t = trace.part_left.front().device_time_ns - camera_offset;
        Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
        for (const auto& q : laser_positions) centroid += q;
        centroid /= static_cast<double>(laser_positions.size());
        const double depth = ((track.poseAt(t) * rig->head_from_left).inverse() * centroid).z();
        const double line_px = (grid == "circle" ? rings.line_width : squares.line_width) * rig->left.matrix(0, 0) / depth;
        if (depth > 0 && line_px < 1.5)
          std::printf("              the printed line is %.1f px wide in these images; the stereo path needs about "
                      "1.5 px or more (quick sessions render at a quarter of the resolution)\n", line_px);
      }
    }

    // 5. Write.
    fitting::Cloud cloud = registration::toCloud(elements);
    fitting::PlyWriteOptions w;
    w.format = opt->ascii ? fitting::PlyFormat::Ascii : fitting::PlyFormat::BinaryLittleEndian;
    w.comment = "StampScan Cloud4D from " + fs::path(opt->input).filename().string();
    fitting::writePly(opt->output, cloud, w);
    std::printf("  wrote       %s: %zu points\n", opt->output.c_str(), cloud.size());
    if (!opt->fit.empty()) {
      const FitOutcome outcome = runFit(cloud, fitting::FitParams{}, nullptr, !opt->quiet);
      fitting::writePly(opt->fit, outcome.surface, w);
      std::printf("  fit         %s (%.2f s)\n", opt->fit.c_str(), clock.lap());
    }
    const double total_s = clock.total();
    std::printf("  time        %.2f s for a %.1f s scan (%.1fx faster than the scan)\n", total_s, trace.scan_seconds,
                trace.scan_seconds / std::max(total_s, 1e-9));
    return 0;
  };
}

}  // namespace stampscan::station
