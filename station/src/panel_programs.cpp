#include "panel_programs.hpp"

#include "stampscan/acquisition/part_planner.hpp"
#include "stampscan/acquisition/trace/rigid_pose.hpp"
#include "program_library.hpp"

#include <fstream>
#include <functional>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace stampscan::station {

namespace {

namespace fs = std::filesystem;

// What the program's plan is predicted to see of its model (as `station plan` prints it, at 2 mm
// samples: a few thousand points to draw), the samples carried onto the fixture like the model's STL.
hmi::ProgramCoverage predictedCoverage(const acquisition::PartProgram& program, const acquisition::CellConfig& config) {
  acquisition::CoverageOptions options;
  options.sample_spacing_mm = 2;
  const acquisition::Coverage c =
      acquisition::predictCoverage(program.model, program.plan, config.geometry, config.limits, options);
  hmi::ProgramCoverage out;
  out.grid_area_mm2 = c.grid_area;
  out.spacing_mm = options.sample_spacing_mm;
  out.laser = c.share(c.laser_area);
  out.stereo = c.share(c.stereo_area);
  out.either = c.share(c.either_area);
  out.sweeps = program.plan.sweepCount(acquisition::Scene::Part);
  out.views = program.plan.stereoCount(acquisition::Scene::Part);
  const Eigen::Isometry3d machine_from_datum = trace::toIsometry(acquisition::toRigidPose(config.geometry.fixture.datum));
  for (std::size_t i = 0; i < c.points.size(); ++i) {
    const Eigen::Vector3d q = machine_from_datum * Eigen::Vector3d(c.points[i][0], c.points[i][1], c.points[i][2]);
    for (int k = 0; k < 3; ++k) out.xyz.push_back(static_cast<float>(q[k]));
    out.seen.push_back(static_cast<std::uint8_t>((c.laser_passes[i] > 0 ? 1 : 0) | (c.stereo[i] ? 2 : 0)));
  }
  return out;
}

// Something of each program computed once and kept while the panel serves (a STEP model is
// tessellated on reading; a prediction casts a ray per sample and sensor), until the program's folder
// changes (a plan written from the command line, a new model).
template <typename T>
class PerProgram {
 public:
  // `stamp` tells the program folder's state; taken again after `make`, which may write the folder
  // (a virtual cell's own program on first use).
  T get(const std::string& name, const std::function<std::string()>& stamp, const std::function<T()>& make) {
    {
      std::lock_guard lock(mutex_);
      if (const auto it = kept_.find(name); it != kept_.end() && it->second.first == stamp()) return it->second.second;
    }
    T value = make();
    return put(name, stamp(), std::move(value));
  }
  T put(const std::string& name, const std::string& stamp, T value) {
    std::lock_guard lock(mutex_);
    return kept_.insert_or_assign(name, std::pair(stamp, std::move(value))).first->second.second;
  }

 private:
  std::mutex mutex_;
  std::map<std::string, std::pair<std::string, T>> kept_;
};

// The program folder's files as they stand (names, sizes, times written); empty when the program
// is not written yet.
std::string programStamp(const std::string& name, const acquisition::CellConfig& config, bool virtual_cell,
                         const fs::path& runs) {
  std::string stamp;
  try {
    const fs::path folder = acquisition::findProgram(programLibrary(config, virtual_cell, runs), name);
    std::error_code ec;
    for (const fs::directory_entry& e : fs::directory_iterator(folder, ec)) {
      if (!e.is_regular_file(ec)) continue;
      stamp += e.path().filename().string() + ':' + std::to_string(e.file_size(ec)) + ':' +
               std::to_string(e.last_write_time(ec).time_since_epoch().count()) + ';';
    }
  } catch (const std::exception&) {
    return {};  // not written yet (a virtual cell writes its own on first use) or not there: its reader says
  }
  return stamp;
}

// The 3D view's program model, what its plan is predicted to see, and planning it on request.
void addProgramViews(hmi::CellPrograms& p, const acquisition::CellConfig& config, bool virtual_cell, const fs::path& runs) {
  const auto stamp = [=](const std::string& name) {
    return std::function<std::string()>([=] { return programStamp(name, config, virtual_cell, runs); });
  };
  auto models = std::make_shared<PerProgram<std::string>>();
  p.model_stl = [=](const std::string& name) {
    return models->get(name, stamp(name), [&] {
      // Where the fixture holds the part: in the frame of the scan's cloud and surface.
      return acquisition::binaryStl(
          acquisition::placeOnFixture(programFromLibrary(name, config, virtual_cell, runs).model, config.geometry));
    });
  };
  auto predicted = std::make_shared<PerProgram<hmi::ProgramCoverage>>();
  p.coverage = [=](const std::string& name) {
    return predicted->get(name, stamp(name), [&] {
      const acquisition::PartProgram program = programFromLibrary(name, config, virtual_cell, runs);
      if (!program.hasPlan()) throw std::runtime_error(name + " has no scan plan yet: Plan makes one from its model");
      return predictedCoverage(program, config);
    });
  };
  p.plan = [=](const std::string& name) {
    acquisition::PartProgram program = programFromLibrary(name, config, virtual_cell, runs);
    program.plan = generatedPlan(program, config);
    adoptPlan(program, program.plan);
    hmi::ProgramCoverage coverage = predictedCoverage(program, config);
    return predicted->put(name, stamp(name)(), std::move(coverage));
  };
}

}  // namespace

hmi::CellPrograms panelPrograms(const acquisition::CellConfig& config, bool virtual_cell, const fs::path& runs,
                                std::uint64_t seed, VirtualCellHost* host) {
  hmi::CellPrograms p;
  p.list = [=] {
    std::vector<hmi::ProgramSummary> out;
    std::set<std::string> names;
    fs::path library;
    try {
      library = programLibrary(config, virtual_cell, runs);
    } catch (const std::exception&) {
      return out;  // the cell has no library
    }
    std::error_code ec;
    const std::vector<fs::path> dirs = fs::is_directory(library, ec) ? acquisition::listPrograms(library)
                                                                      : std::vector<fs::path>{};  // none written yet
    for (const fs::path& dir : dirs) {
      std::ifstream in(dir / acquisition::kProgramFile, std::ios::binary);
      std::ostringstream text;
      text << in.rdbuf();
      try {
        const acquisition::PartProgram program = acquisition::parseProgramFile(text.str(), (dir / acquisition::kProgramFile).string());
        names.insert(program.name);
        out.push_back({program.name, program.description, program.grid.kind, program.material, program.grid.pitch_mm,
                       program.sheet_thickness_mm, program.hasPlan() ? "" : "not planned yet",
                       lineNumberOf(program, virtual_cell), program.hasPlan()});
      } catch (const std::exception& e) {
        out.push_back({dir.filename().string(), "", "", "", 0, 0, std::string("unreadable: ") + e.what(), std::nullopt, false});
      }
    }
    if (virtual_cell)
      for (const SimulatedProgramName& simulated : simulatedProgramNames())
        if (names.count(simulated.name) == 0)
          out.push_back({simulated.name,
                         "the virtual cell's simulated " + simulated.part + " (" + simulated.grid + " grid)" +
                             (simulated.sample_region ? ", its sample region" : ""),
                         simulated.grid, "DC04", 2.54, 0.8, "written into the library on first use",
                         simulated.line_number, true});
    return out;
  };
  p.prepare = [=](const std::string& name) {
    const acquisition::PartProgram program = programFromLibrary(name, config, virtual_cell, runs);
    hmi::ProgramScan scan;
    // The panel's sessions are quick ones (the virtual cameras at a quarter of their resolution):
    // half the cell's calibration scenes.
    scan.plan = programPlan(program, config, acquisition::calibrationScenes(config.calibration, 0.5, seed), true);
    scan.plan.name = program.name + ", laser and stereo, with calibration scenes";
    scan.material = program.material;
    scan.press_program = program.press_program;
    scan.program = {program.name, program.folder.string()};
    if (host != nullptr && host->started()) {
      host->useProgram(program);
      scan.truth = host->truthOfScan(scan.plan);
    }
    return scan;
  };
  addProgramViews(p, config, virtual_cell, runs);
  p.by_line_number = [=](std::uint16_t line_number) {
    return programByLineNumber(line_number, config, virtual_cell, runs);
  };
  if (host != nullptr) p.restore = [host] { host->useOwnPart(); };
  return p;
}

}  // namespace stampscan::station
