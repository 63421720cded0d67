// The report of a synthetic run folder, checked by content: the colour at places of known strain on
// the maps, the FLC where the formula puts it on the FLD, the PDF's pages, the CSV's rows, the HTML's
// embedded images; and failures that leave the folder as it was.
#include "report_test_support.hpp"
#include "stampscan/report/fld_plot.hpp"
#include "stampscan/report/run_report.hpp"
#include "stampscan/report/strain_map.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iterator>

namespace stampscan::report::test {
namespace {

std::string readFile(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::size_t countOf(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + what.size())) ++n;
  return n;
}

ReportOptions options(const std::string& material, const std::string& program = "") {
  ReportOptions o;
  o.material = material;
  o.program = program;
  return o;
}

const View& viewNamed(const std::vector<View>& views, const std::string& name) {
  return *std::find_if(views.begin(), views.end(), [&](const View& v) { return v.name == name; });
}

class ReportFiles : public ScratchTest {
 protected:
  void SetUp() override {
    ScratchTest::SetUp();
    plate_ = makePlate();
    run_ = root() / "20260105-101500-plate-7";
    writePlateRun(run_, plate_);
  }
  // Where an element-coloured pixel of a map should be, and the colour it should have: the top view of
  // the flat plate faces the viewer, so the band colour comes through unshaded. Returns false when
  // the value lies too close to a band edge to tell the bands apart.
  bool expectedPixel(MapQuantity q, double x, double y, int& px, int& py, Rgb& colour) const {
    const Material& m = builtInMaterials().find(kDefaultMaterial);
    const StrainAnalysis a = analyseStrains(plate_.elements, m);
    const ColourScale scale = scaleFor(q, a, m);
    const double e1 = engineeringPercent(plateMajorTrue(x));
    const double value = q == MapQuantity::Thinning      ? thinningPercent(-plateMajorTrue(x))
                         : q == MapQuantity::MajorStrain ? e1
                                                         : m.flc.marginAlongPath(0, e1);
    const auto& edges = scale.edges();
    const double band = edges[1] - edges[0];
    for (const double edge : edges)
      if (std::abs(value - edge) < 0.2 * band) return false;
    const ViewProjection projection(viewNamed(standardViews(), "top"), plate_.mesh.vertices.positions,
                                    StrainMapLayout::map_width, StrainMapLayout::map_height);
    const Eigen::Vector3d p = projection.toPixel(fitting::Vec3(x, y, 0));
    px = StrainMapLayout::map_x + static_cast<int>(std::floor(p.x()));
    py = StrainMapLayout::map_y + static_cast<int>(std::floor(p.y()));
    colour = scale.colourOf(value);
    return true;
  }

  PlateRun plate_;
  fs::path run_;
};

TEST_F(ReportFiles, WritesEveryFileAndNothingElse) {
  const auto before = folderEntries(run_);
  const ReportSummary s = writeRunReport(run_);
  EXPECT_EQ(s.material, "DC04");
  EXPECT_EQ(s.material_source, MaterialSource::Default);
  EXPECT_TRUE(s.drawn_from_mesh);
  EXPECT_EQ(s.run.part_id, "plate-7");
  EXPECT_EQ(s.run.program, "OP20");
  EXPECT_EQ(s.run.date, "2026-01-05 10:15:00");
  EXPECT_EQ(s.elements, plate_.elements.size());
  EXPECT_EQ(s.verdict, Verdict::Failed) << s.verdict_reason;  // the last columns are over the FLC
  EXPECT_GT(s.zone_counts[static_cast<std::size_t>(Zone::Marginal)], 0u);
  EXPECT_GT(s.zone_counts[static_cast<std::size_t>(Zone::InsufficientStretch)], 0u);
  std::set<std::string> expected = before;
  for (const MapQuantity q : kMapQuantities)
    for (const View& v : standardViews()) expected.insert(strainMapFileName(q, v));
  for (const char* name : {"fld.png", "report.pdf", "report.html", "elements.csv", "report.json"})
    expected.insert(name);
  EXPECT_EQ(folderEntries(run_), expected);  // no temporary left behind
  EXPECT_EQ(s.files.size(), expected.size() - before.size());
  const nlohmann::json j = nlohmann::json::parse(readFile(run_ / "report.json"));
  EXPECT_EQ(j["verdict"], "failed");
  EXPECT_EQ(j["material"], "DC04");
}

TEST_F(ReportFiles, MapColoursAreThoseOfTheStrainAtThatPlace) {
  writeRunReport(run_);
  int checked = 0;
  for (const MapQuantity q : kMapQuantities) {
    const Png png(run_ / strainMapFileName(q, viewNamed(standardViews(), "top")));
    ASSERT_EQ(png.width(), StrainMapLayout::width);
    ASSERT_EQ(png.height(), StrainMapLayout::height);
    // Along the middle row, away from the worst-spot markers at the right-hand end.
    for (double x = 6.25; x <= 70; x += 5) {
      int px = 0, py = 0;
      Rgb colour{};
      if (!expectedPixel(q, x, 31.25, px, py, colour)) continue;
      const auto got = png.at(px, py);
      for (int k = 0; k < 3; ++k)
        EXPECT_NEAR(got[static_cast<std::size_t>(k)], colour[static_cast<std::size_t>(k)], 1)
            << fileStem(q) << " at x = " << x << " mm, pixel " << px << ", " << py;
      ++checked;
    }
  }
  EXPECT_GE(checked, 15);
}

TEST_F(ReportFiles, FldDrawsTheFlcWhereTheFormulaPutsIt) {
  writeRunReport(run_);
  const Png png(run_ / "fld.png");
  ASSERT_EQ(png.width(), FldLayout::width);
  const Material& m = builtInMaterials().find(kDefaultMaterial);
  const FldAxes axes = fldPngAxes(analyseStrains(plate_.elements, m), m);
  const auto darkNear = [&](double minor, double major, int reach) {
    const Eigen::Vector2d d = axes.toDrawing(minor, major);
    for (int dy = -reach; dy <= reach; ++dy)
      for (int dx = -reach; dx <= reach; ++dx) {
        const auto c = png.at(static_cast<int>(d.x()) + dx, static_cast<int>(d.y()) + dy);
        if (c[0] < 70 && c[1] < 70 && c[2] < 70) return true;
      }
    return false;
  };
  // The curve is drawn black; FLC0 = (23.3 + 14.13 t) n / 0.21 for DC04 (t = 1 mm, n = 0.21).
  EXPECT_NEAR(m.flc.flc0(), 37.43, 1e-9);
  for (const double minor : {-17.0, -8.0, 0.0, 7.0, 16.0}) {
    EXPECT_TRUE(darkNear(minor, m.flc.majorAt(minor), 2)) << "no curve at e2 = " << minor;
    EXPECT_FALSE(darkNear(minor, m.flc.majorAt(minor) - 5, 2))
        << "a curve where there is none, 5% below e2 = " << minor;
  }
  // The elements lie on the plane-strain axis, coloured by zone.
  const Eigen::Vector2d failure = axes.toDrawing(0, engineeringPercent(plateMajorTrue(100)));
  const auto c = png.at(static_cast<int>(failure.x()), static_cast<int>(failure.y()));
  const Rgb red = zoneColour(Zone::Failure);
  EXPECT_EQ((std::array<int, 3>{c[0], c[1], c[2]}), (std::array<int, 3>{red[0], red[1], red[2]}));
}

TEST_F(ReportFiles, PdfIsA4WithItsPages) {
  writeRunReport(run_, options("DC06", "OP30"));
  const std::string pdf = readFile(run_ / "report.pdf");
  EXPECT_EQ(pdf.rfind("%PDF-", 0), 0u);
  EXPECT_EQ(countOf(pdf, "/Type /Page") - countOf(pdf, "/Type /Pages"), 3u);
  EXPECT_EQ(countOf(pdf, "/MediaBox [ 0 0 595.276 841.89 ]"), 3u);  // A4 in points
  EXPECT_NE(pdf.find("%%EOF"), std::string::npos);
  const std::string html = readFile(run_ / "report.html");
  EXPECT_NE(html.find("OP30"), std::string::npos);
  EXPECT_NE(html.find("DC06"), std::string::npos);
}

TEST_F(ReportFiles, CsvHasOneRowPerElement) {
  writeRunReport(run_);
  const std::string csv = readFile(run_ / "elements.csv");
  EXPECT_EQ(static_cast<std::size_t>(std::count(csv.begin(), csv.end(), '\n')), plate_.elements.size() + 1);
  EXPECT_EQ(csv.rfind("element,x_mm,y_mm,z_mm,major_true_strain,minor_true_strain,thickness_true_strain,", 0), 0u);
  EXPECT_NE(csv.find(",failure,"), std::string::npos);
  EXPECT_NE(csv.find(",insufficient stretch,"), std::string::npos);
}

TEST_F(ReportFiles, HtmlIsOneSelfContainedPage) {
  writeRunReport(run_);
  const std::string html = readFile(run_ / "report.html");
  EXPECT_EQ(countOf(html, "src=\"data:image/png;base64,"), 13u);  // 12 maps and the FLD
  EXPECT_EQ(countOf(html, "src=\""), 13u);                        // and no link to a file
  EXPECT_NE(html.find("plate-7"), std::string::npos);
  EXPECT_NE(html.find("failed"), std::string::npos);
}

TEST_F(ReportFiles, WithoutAMeshTheElementsAreDrawn) {
  fs::remove(run_ / "mesh.ply");
  const ReportSummary s = writeRunReport(run_);
  EXPECT_FALSE(s.drawn_from_mesh);
  const Png png(run_ / "thinning-top.png");
  int checked = 0;
  for (double x = 10; x <= 70; x += 5) {
    int px = 0, py = 0;
    Rgb colour{};
    if (!expectedPixel(MapQuantity::Thinning, x, 30, px, py, colour)) continue;
    // The projection is fitted to the elements, which span the same plate as the mesh.
    const auto got = png.at(px, py);
    EXPECT_NEAR(got[0], colour[0], 1) << x;
    EXPECT_NEAR(got[1], colour[1], 1) << x;
    EXPECT_NEAR(got[2], colour[2], 1) << x;
    ++checked;
  }
  EXPECT_GE(checked, 6);
}

void expectFailureLeavesFolder(const fs::path& run, const ReportOptions& o, const std::string& named) {
  const auto before = folderEntries(run);
  try {
    writeRunReport(run, o);
    FAIL() << "no error";
  } catch (const ReportError& e) {
    EXPECT_NE(std::string(e.what()).find(named), std::string::npos) << e.what();
  }
  EXPECT_EQ(folderEntries(run), before);
}

TEST_F(ReportFiles, BadInputsLeaveTheFolderAsItWas) {
  expectFailureLeavesFolder(run_, options("unobtainium"), "unobtainium");
  const std::string cloud = readFile(run_ / "cloud4d.ply");
  fitting::writeFileAtomically(run_ / "cloud4d.ply", cloud.substr(0, cloud.size() / 2));
  expectFailureLeavesFolder(run_, {}, "cloud4d.ply");
  fs::remove(run_ / "cloud4d.ply");
  expectFailureLeavesFolder(run_, {}, "cloud4d.ply");
  writePlateRun(run_, plate_);
  fitting::writeFileAtomically(run_ / "run.json", "{\"part_id\": ");
  expectFailureLeavesFolder(run_, {}, "run.json");
}

TEST_F(ReportFiles, MaterialFromRunJsonAndFromTheOption) {
  fitting::writeFileAtomically(run_ / "run.json", R"({"part_id": "p", "material": "AA5182-O"})");
  ReportSummary s = writeRunReport(run_);
  EXPECT_EQ(s.material, "AA5182-O");
  EXPECT_EQ(s.material_source, MaterialSource::RunJson);
  s = writeRunReport(run_, options("dc04"));
  EXPECT_EQ(s.material, "DC04");
  EXPECT_EQ(s.material_source, MaterialSource::Option);
}

}  // namespace
}  // namespace stampscan::report::test
