// writeRunReport: a run folder's clouds in, the report files out (run_report.hpp).
#include "stampscan/report/run_report.hpp"

#include "fld_drawing.hpp"
#include "report_document.hpp"
#include "stampscan/fitting/atomic_file.hpp"
#include "stampscan/fitting/kdtree.hpp"
#include "stampscan/fitting/ply_io.hpp"
#include "strain_map_drawing.hpp"

#include <nlohmann/json.hpp>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <chrono>
#include <cmath>
#include <ctime>
#include <fstream>
#include <limits>
#include <memory>
#include <optional>

namespace stampscan::report {

namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;
double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

std::string now() {
  const std::time_t t = std::time(nullptr);
  std::tm local{};
  localtime_r(&t, &local);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%d %H:%M", &local);
  return text;
}

// The run's measured elements. Required: without them there is nothing to report.
fitting::Cloud readElements(const fs::path& file) {
  std::error_code error;
  if (!fs::exists(file, error)) throw ReportError(file.string() + ": missing (the run's measured grid elements)");
  try {
    return fitting::readPly(file);
  } catch (const std::exception& e) {
    throw ReportError(file.string() + ": damaged: " + e.what());
  }
}

// The fitted mesh when the run has one with triangles.
std::optional<fitting::Mesh> readMesh(const fs::path& file) {
  std::error_code error;
  if (!fs::exists(file, error)) return std::nullopt;
  try {
    fitting::Mesh mesh = fitting::readPlyMesh(file);
    if (mesh.triangles.empty()) return std::nullopt;
    return mesh;
  } catch (const std::exception& e) {
    throw ReportError(file.string() + ": damaged: " + e.what());
  }
}

// Element values carried to the mesh vertices: inverse-distance weights of the nearest elements,
// none (NaN) where no element is within a few grid pitches (a hole in the measurement).
class ElementsToVertices {
 public:
  ElementsToVertices(const StrainAnalysis& a, const std::vector<fitting::Vec3>& vertices) {
    std::vector<fitting::Vec3> positions(a.elements.size());
    for (std::size_t i = 0; i < positions.size(); ++i) positions[i] = a.elements[i].position;
    const fitting::KdTree tree(positions);
    const double reach_sq = std::pow(3.0 * a.grid_pitch_mm, 2);
    const double soft = std::pow(0.05 * a.grid_pitch_mm, 2);
    weights_.resize(vertices.size());
    tbb::parallel_for(std::size_t{0}, vertices.size(), [&](std::size_t v) {
      std::vector<fitting::Neighbor> found;
      tree.knn(vertices[v], 4, found);
      for (const fitting::Neighbor& n : found)
        if (n.distance_sq <= reach_sq) weights_[v].push_back({n.index, 1.0 / (n.distance_sq + soft)});
    });
  }
  std::vector<double> apply(const std::vector<double>& element_values) const {
    std::vector<double> out(weights_.size(), std::numeric_limits<double>::quiet_NaN());
    for (std::size_t v = 0; v < weights_.size(); ++v) {
      double sum = 0, total = 0;
      for (const auto& [element, w] : weights_[v]) {
        // The margin of a path that never meets the FLC is infinite; any value past the scale's
        // top band draws the same.
        sum += w * std::min(element_values[element], 1e3);
        total += w;
      }
      if (total > 0) out[v] = sum / total;
    }
    return out;
  }

 private:
  std::vector<std::vector<std::pair<std::uint32_t, double>>> weights_;
};

std::string csvNumber(double v, int decimals) {
  if (!std::isfinite(v)) return "";  // a spreadsheet reads an empty cell as "no value"
  char text[48];
  std::snprintf(text, sizeof text, "%.*f", decimals, v);
  return text;
}

std::string elementsCsv(const StrainAnalysis& a) {
  std::string out =
      "element,x_mm,y_mm,z_mm,major_true_strain,minor_true_strain,thickness_true_strain,major_engineering_percent,"
      "minor_engineering_percent,thinning_percent,flc_major_engineering_percent,safety_margin_percent,zone,patch_"
      "elements,thickness_strain_uncertainty\n";
  out.reserve(out.size() + a.elements.size() * 140);
  for (const ElementStrain& e : a.elements) {
    out += std::to_string(e.index) + "," + csvNumber(e.position.x(), 3) + "," + csvNumber(e.position.y(), 3) + "," +
           csvNumber(e.position.z(), 3) + "," + csvNumber(e.major_true, 5) + "," + csvNumber(e.minor_true, 5) + "," +
           csvNumber(e.thickness_true, 5) + "," + csvNumber(e.major_percent, 3) + "," + csvNumber(e.minor_percent, 3) +
           "," + csvNumber(e.thinning_percent, 3) + "," + csvNumber(e.flc_major_percent, 3) + "," +
           csvNumber(e.margin_percent, 3) + "," + toString(e.zone) + "," + std::to_string(e.patch_size) + "," +
           csvNumber(e.thickness_uncertainty, 5) + "\n";
  }
  return out;
}

std::string reportJson(const ReportSummary& s, const StrainAnalysis& a, const Material& m) {
  nlohmann::json j = {{"part_id", s.run.part_id},
                      {"program", s.run.program},
                      {"part_program", s.run.part_program},
                      {"material", m.name},
                      {"material_source", toString(s.material_source)},
                      {"flc", m.flc.describe()},
                      {"safety_margin_percent", m.safety_margin_percent},
                      {"verdict", toString(a.verdict)},
                      {"verdict_reason", a.verdict_reason},
                      {"elements", a.elements.size()},
                      {"elements_in_cloud", a.elements_in_cloud},
                      {"elements_left_out", a.left_out},
                      {"max_thinning_percent", a.max_thinning_percent},
                      {"min_margin_percent", std::isfinite(a.min_margin_percent) ? nlohmann::json(a.min_margin_percent)
                                                                                 : nlohmann::json(nullptr)}};
  for (std::size_t z = 0; z < kZoneCount; ++z) j["zones"][toString(static_cast<Zone>(z))] = a.zone_counts[z];
  for (const WorstSpot& w : a.worst_spots) {
    const ElementStrain& e = a.elements[w.element];
    j["worst_spots"].push_back({{"element", e.index},
                                {"position_mm", {e.position.x(), e.position.y(), e.position.z()}},
                                {"major_engineering_percent", e.major_percent},
                                {"minor_engineering_percent", e.minor_percent},
                                {"thinning_percent", e.thinning_percent},
                                {"safety_margin_percent", e.margin_percent},
                                {"zone", toString(e.zone)},
                                {"patch_elements", w.patch_size},
                                {"counted", w.counted}});
    // The thickness strain's expanded uncertainty (k = 2, about 95 %), when the measurement states it.
    if (std::isfinite(e.thickness_uncertainty))
      j["worst_spots"].back()["thickness_strain_expanded_uncertainty"] = 2 * e.thickness_uncertainty;
  }
  return j.dump(2) + "\n";
}

// The report's files, each written under its temporary name, renamed together at the end.
class PendingFiles {
 public:
  explicit PendingFiles(fs::path dir) : dir_(std::move(dir)) {}
  fs::path add(const std::string& name) {
    files_.push_back(std::make_unique<fitting::AtomicFile>(dir_ / name));
    return files_.back()->temporaryPath();
  }
  void write(const std::string& name, const std::string& bytes) {
    const fs::path temporary = add(name);
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.close();
    if (!out) throw std::runtime_error((dir_ / name).string() + ": cannot be written");
  }
  std::vector<fs::path> commit() {
    std::vector<fitting::AtomicFile*> all;
    std::vector<fs::path> targets;
    for (const auto& f : files_) {
      all.push_back(f.get());
      targets.push_back(f->target());
    }
    fitting::commitTogether(all);
    return targets;
  }

 private:
  fs::path dir_;
  std::vector<std::unique_ptr<fitting::AtomicFile>> files_;
};

}  // namespace

const char* toString(MaterialSource source) {
  switch (source) {
    case MaterialSource::Option: return "option";
    case MaterialSource::RunJson: return "run.json";
    case MaterialSource::Default: return "default";
  }
  return "?";
}

namespace {

// The material: the option's, else run.json's, else the default; the summary says which.
const Material& chooseMaterial(const ReportOptions& options, ReportSummary& summary) {
  const MaterialLibrary& library = options.materials ? *options.materials : builtInMaterials();
  std::string material_name = options.material;
  summary.material_source = MaterialSource::Option;
  if (material_name.empty()) {
    material_name = summary.run.material.empty() ? kDefaultMaterial : summary.run.material;
    summary.material_source = summary.run.material.empty() ? MaterialSource::Default : MaterialSource::RunJson;
  }
  try {
    const Material& material = library.find(material_name);
    summary.material = material.name;
    return material;
  } catch (const MaterialError& e) {
    throw ReportError(e.what());
  }
}

// Each map quantity's values at the mesh's vertices. The thinning is the fitted surface's own strain
// field where the mesh carries it (the field the fit made from the elements, as fitted.ply and the
// panel show it), not a second interpolation of the elements.
std::vector<std::vector<double>> vertexValues(const StrainAnalysis& analysis, const fitting::Mesh& mesh,
                                              const std::vector<std::vector<double>>& element_values) {
  std::vector<std::vector<double>> vertex_values;
  const ElementsToVertices carry(analysis, mesh.vertices.positions);
  const std::vector<double>& strain = mesh.vertices.strain;
  for (std::size_t q = 0; q < element_values.size(); ++q) {
    if (kMapQuantities[q] == MapQuantity::Thinning && strain.size() == mesh.vertices.size()) {
      std::vector<double> thinning(strain.size(), std::numeric_limits<double>::quiet_NaN());
      for (std::size_t v = 0; v < strain.size(); ++v)
        if (std::isfinite(strain[v])) thinning[v] = thinningPercent(strain[v]);
      vertex_values.push_back(std::move(thinning));
    } else {
      vertex_values.push_back(carry.apply(element_values[q]));
    }
  }
  return vertex_values;
}

// The maps (every quantity from every view) and the FLD, rendered and encoded in parallel.
struct DrawnMaps {
  std::vector<ColourScale> scales;
  std::vector<draw::MapRaster> maps;
  std::vector<std::string> map_pngs;
  std::string fld_png;
};

DrawnMaps drawMaps(const StrainAnalysis& analysis, const Material& material, const std::optional<fitting::Mesh>& mesh,
                   const std::string& title_tail) {
  DrawnMaps d;
  const std::vector<View> views = standardViews();
  std::vector<std::vector<double>> element_values;
  for (const MapQuantity q : kMapQuantities) {
    d.scales.push_back(scaleFor(q, analysis, material));
    element_values.push_back(quantityValues(analysis, q));
  }
  std::vector<fitting::Vec3> element_positions(analysis.elements.size());
  for (std::size_t i = 0; i < element_positions.size(); ++i) element_positions[i] = analysis.elements[i].position;
  const std::vector<std::vector<double>> vertex_values = mesh ? vertexValues(analysis, *mesh, element_values)
                                                              : std::vector<std::vector<double>>{};
  const std::vector<fitting::Vec3>& surface_points = mesh ? mesh->vertices.positions : element_positions;

  using L = StrainMapLayout;
  const std::size_t map_count = std::size(kMapQuantities) * views.size();
  d.maps.resize(map_count);
  d.map_pngs.resize(map_count);
  tbb::parallel_invoke(
      [&] {
        tbb::parallel_for(std::size_t{0}, map_count, [&](std::size_t k) {
          const std::size_t q = k / views.size();
          const View& view = views[k % views.size()];
          const ViewProjection projection(view, surface_points, L::map_width, L::map_height);
          const RenderedView rendered =
              mesh ? renderMesh(*mesh, vertex_values[q], projection)
                   : renderPoints(element_positions, element_values[q], 0.6 * analysis.grid_pitch_mm, projection);
          draw::MapRaster& map = d.maps[k];
          map.quantity = kMapQuantities[q];
          map.view = view;
          map.raster = draw::colourRaster(rendered, d.scales[q]);
          map.pixels_per_mm = projection.pixelsPerMm();
          for (std::size_t s = 0; s < analysis.worst_spots.size(); ++s) {
            const fitting::Vec3& p = analysis.elements[analysis.worst_spots[s].element].position;
            if (!visible(rendered, projection, p, 2.0 * analysis.grid_pitch_mm)) continue;
            const Eigen::Vector3d px = projection.toPixel(p);
            map.spots.push_back({px.x(), px.y(), static_cast<int>(s + 1)});
          }
          d.map_pngs[k] = draw::strainMapPng(
              map, d.scales[q], std::string(caption(map.quantity)) + ", " + view.name + " view" + title_tail);
        });
      },
      [&] { d.fld_png = draw::fldPng(analysis, material, "Forming-limit diagram" + title_tail); });
  return d;
}

// The maps, the FLD, the PDF and the HTML page into the pending files.
void writeDrawings(const ReportSummary& summary, const StrainAnalysis& analysis, const Material& material,
                   const DrawnMaps& drawn, PendingFiles& files) {
  draw::ReportContent content;
  content.run = &summary.run;
  content.program = summary.run.program;
  content.material = &material;
  content.material_note = summary.material_source == MaterialSource::Default
                              ? std::string("the default: run.json names no material (choose one with --material)")
                          : summary.material_source == MaterialSource::RunJson ? "as run.json names it"
                                                                               : "";
  content.analysis = &analysis;
  content.generated = now();
  content.maps = &drawn.maps;
  content.scales = &drawn.scales;
  std::vector<std::pair<std::string, const std::string*>> images;
  for (std::size_t k = 0; k < drawn.maps.size(); ++k) {
    const std::string name = strainMapFileName(drawn.maps[k].quantity, drawn.maps[k].view);
    files.write(name, drawn.map_pngs[k]);
    images.emplace_back(name, &drawn.map_pngs[k]);
  }
  files.write("fld.png", drawn.fld_png);
  images.emplace_back("fld.png", &drawn.fld_png);
  const fs::path pdf = files.add("report.pdf");
  std::string page;
  tbb::parallel_invoke([&] { draw::writePdf(pdf, content); }, [&] { page = draw::html(content, images); });
  files.write("report.html", page);
}

}  // namespace

ReportSummary writeRunReport(const fs::path& run_dir, const ReportOptions& options) {
  const auto t0 = Clock::now();
  ReportSummary summary;
  summary.run_dir = run_dir;
  std::error_code error;
  if (!fs::is_directory(run_dir, error)) throw ReportError(run_dir.string() + ": not a run folder (no such directory)");

  // Inputs, all checked before anything is written.
  summary.run = readRunInfo(run_dir);
  if (!options.program.empty()) summary.run.program = options.program;
  const Material& material = chooseMaterial(options, summary);
  const fs::path cloud_file = run_dir / "cloud4d.ply";
  const fitting::Cloud cloud = readElements(cloud_file);
  const std::optional<fitting::Mesh> mesh = readMesh(run_dir / "mesh.ply");
  summary.drawn_from_mesh = mesh.has_value();

  StrainAnalysis analysis;
  try {
    analysis = analyseStrains(cloud, material, options.analysis);
  } catch (const std::invalid_argument& e) {
    throw ReportError(cloud_file.string() + ": " + e.what());
  }
  // A scan that lacks data may miss the very spot that fails: what it measured cannot call the part good.
  if (!summary.run.data_loss.empty() && analysis.verdict == Verdict::Good) {
    analysis.verdict = Verdict::Marginal;
    analysis.verdict_reason = "the measured elements are good, but the scan is incomplete (" + summary.run.data_loss +
                              "): scan the part again";
  }

  const auto t_draw = Clock::now();
  const DrawnMaps drawn = drawMaps(analysis, material, mesh, ": part " + summary.run.part_id + ", " + material.name);
  PendingFiles files(run_dir);
  writeDrawings(summary, analysis, material, drawn, files);
  summary.drawing_seconds = secondsSince(t_draw);

  files.write("elements.csv", elementsCsv(analysis));
  summary.verdict = analysis.verdict;
  summary.verdict_reason = analysis.verdict_reason;
  summary.elements_left_out = analysis.left_out;
  summary.elements = analysis.elements.size();
  summary.zone_counts = analysis.zone_counts;
  summary.max_thinning_percent = analysis.max_thinning_percent;
  summary.min_margin_percent = analysis.min_margin_percent;
  files.write("report.json", reportJson(summary, analysis, material));
  summary.files = files.commit();
  summary.seconds = secondsSince(t0);
  return summary;
}

}  // namespace stampscan::report
