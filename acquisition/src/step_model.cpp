// STEP models through Open CASCADE: reading (every face, tessellated) and writing a height field as
// one B-spline face; and loadNominalModel, which picks the reader by the file's extension. The only
// file that includes Open CASCADE's headers: they are heavy, and their types stay out of the API.
#include "stampscan/acquisition/nominal_model.hpp"

#include "stampscan/fitting/atomic_file.hpp"

#include <BRepBuilderAPI_MakeFace.hxx>
#include <BRepMesh_IncrementalMesh.hxx>
#include <BRep_Tool.hxx>
#include <GeomAPI_PointsToBSplineSurface.hxx>
#include <Geom_BSplineSurface.hxx>
#include <IFSelect_ReturnStatus.hxx>
#include <Interface_Static.hxx>
#include <Message.hxx>
#include <Message_Messenger.hxx>
#include <Poly_Triangulation.hxx>
#include <Precision.hxx>
#include <STEPControl_Reader.hxx>
#include <STEPControl_Writer.hxx>
#include <Standard_Failure.hxx>
#include <TColStd_Array2OfReal.hxx>
#include <TopExp_Explorer.hxx>
#include <TopLoc_Location.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Face.hxx>
#include <TopoDS_Shape.hxx>

#include <algorithm>
#include <cctype>
#include <cmath>

namespace stampscan::acquisition {

namespace {

// Open CASCADE's own exceptions do not derive from std::exception.
std::string occtMessage(const Standard_Failure& e) {
  const char* text = e.GetMessageString();
  return std::string(e.DynamicType()->Name()) + (text && *text ? std::string(": ") + text : std::string());
}

void checkReadable(const std::filesystem::path& file) {
  std::error_code ec;
  if (!std::filesystem::exists(file, ec)) throw ModelError(file.string() + ": the model file does not exist");
  if (!std::filesystem::is_regular_file(file, ec)) throw ModelError(file.string() + ": not a regular file, not a model file");
}

// Millimetres both ways: the reader converts whatever unit the file declares to this one, the
// writer declares it. These are process-wide settings of Open CASCADE's translator.
void useMillimetres() {
  Interface_Static::SetCVal("xstep.cascade.unit", "MM");
  Interface_Static::SetCVal("write.step.unit", "MM");
}

// Open CASCADE reports its translations (statistics, the STEP parser's complaints) on the standard
// output through its default messenger. A command's output is its own, and what went wrong reaches
// the caller as a ModelError: the messenger's printers are held back while a file is translated.
class QuietTranslation {
 public:
  QuietTranslation() : saved_(Message::DefaultMessenger()->Printers()) { Message::DefaultMessenger()->ChangePrinters().Clear(); }
  ~QuietTranslation() { Message::DefaultMessenger()->ChangePrinters() = saved_; }
  QuietTranslation(const QuietTranslation&) = delete;
  QuietTranslation& operator=(const QuietTranslation&) = delete;

 private:
  Message_SequenceOfPrinters saved_;
};

}  // namespace

NominalModel loadStep(const std::filesystem::path& file, const StepTessellation& tessellation) {
  checkReadable(file);
  const std::string name = file.string();
  NominalModel model;
  model.source = name;
  std::size_t faces = 0, untessellated = 0;
  try {
    const QuietTranslation quiet;
    useMillimetres();
    STEPControl_Reader reader;
    if (reader.ReadFile(name.c_str()) != IFSelect_RetDone) throw ModelError(name + ": not a readable STEP file");
    if (reader.TransferRoots() == 0) throw ModelError(name + ": the STEP file holds no shape that could be translated");
    const TopoDS_Shape shape = reader.OneShape();
    if (shape.IsNull()) throw ModelError(name + ": the STEP file holds no shape");
    // Relative deflection off: the limits are absolute, in mm. Not in parallel: the caller may be
    // a worker already.
    BRepMesh_IncrementalMesh mesher(shape, tessellation.linear_deflection_mm, false, tessellation.angular_deflection_rad, false);
    for (TopExp_Explorer it(shape, TopAbs_FACE); it.More(); it.Next()) {
      ++faces;
      const TopoDS_Face& face = TopoDS::Face(it.Current());
      TopLoc_Location location;
      const Handle(Poly_Triangulation) mesh = BRep_Tool::Triangulation(face, location);
      if (mesh.IsNull() || mesh->NbTriangles() == 0) {
        ++untessellated;
        continue;
      }
      const gp_Trsf placement = location.Transformation();
      const auto offset = static_cast<std::uint32_t>(model.vertices.size());
      for (Standard_Integer i = 1; i <= mesh->NbNodes(); ++i) {
        const gp_Pnt p = mesh->Node(i).Transformed(placement);
        model.vertices.push_back({p.X(), p.Y(), p.Z()});
      }
      // A reversed face's outside is the other side of its surface: swap two corners.
      const bool reversed = face.Orientation() == TopAbs_REVERSED;
      for (Standard_Integer k = 1; k <= mesh->NbTriangles(); ++k) {
        Standard_Integer a = 0, b = 0, c = 0;
        mesh->Triangle(k).Get(a, b, c);
        if (reversed) std::swap(b, c);
        model.triangles.push_back({offset + static_cast<std::uint32_t>(a - 1), offset + static_cast<std::uint32_t>(b - 1),
                                   offset + static_cast<std::uint32_t>(c - 1)});
      }
    }
  } catch (const Standard_Failure& e) {
    throw ModelError(name + ": Open CASCADE failed on the STEP file: " + occtMessage(e));
  }
  if (faces == 0) throw ModelError(name + ": the STEP file has no faces (only points, curves or an empty shape)");
  if (untessellated > 0)
    throw ModelError(name + ": " + std::to_string(untessellated) + " of the STEP file's " + std::to_string(faces) +
                     " faces could not be tessellated");
  model.check(name);
  return model;
}

void writeStepSurface(const HeightGrid& grid, const std::filesystem::path& file, const StepSurfaceOptions& options) {
  const std::string name = file.string();
  if (grid.columns < 4 || grid.rows < 4 || grid.heights.size() != grid.columns * grid.rows)
    throw ModelError(name + ": a STEP surface needs a height grid of at least 4 x 4 samples, one height per sample");
  for (const double h : grid.heights)
    if (!std::isfinite(h)) throw ModelError(name + ": the height grid has a height that is not a finite number");
  fitting::AtomicFile out(file);
  try {
    const QuietTranslation quiet;
    // Rows of the array run along x (GeomAPI_PointsToBSplineSurface's convention for height grids).
    TColStd_Array2OfReal z(1, static_cast<Standard_Integer>(grid.columns), 1, static_cast<Standard_Integer>(grid.rows));
    for (std::size_t j = 0; j < grid.rows; ++j)
      for (std::size_t i = 0; i < grid.columns; ++i)
        z.SetValue(static_cast<Standard_Integer>(i + 1), static_cast<Standard_Integer>(j + 1), grid.heights[j * grid.columns + i]);
    GeomAPI_PointsToBSplineSurface fit;
    fit.Init(z, grid.x0, grid.dx, grid.y0, grid.dy, options.degree_min, options.degree_max, GeomAbs_C2, options.tolerance_mm);
    if (!fit.IsDone()) throw ModelError(name + ": the B-spline approximation of the height grid failed");
    BRepBuilderAPI_MakeFace face(fit.Surface(), Precision::Confusion());
    if (!face.IsDone()) throw ModelError(name + ": no face could be made on the B-spline surface");
    useMillimetres();
    Interface_Static::SetCVal("write.step.schema", "AP214IS");
    STEPControl_Writer writer;
    if (writer.Transfer(face.Face(), STEPControl_AsIs) != IFSelect_RetDone)
      throw ModelError(name + ": the face could not be translated to STEP");
    if (writer.Write(out.temporaryPath().string().c_str()) != IFSelect_RetDone) throw ModelError(name + ": cannot be written");
  } catch (const Standard_Failure& e) {
    throw ModelError(name + ": Open CASCADE failed writing the surface: " + occtMessage(e));
  }
  out.commit();
}

NominalModel loadNominalModel(const std::filesystem::path& file) {
  std::string ext = file.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext == ".stl") return loadStl(file);
  if (ext == ".step" || ext == ".stp") return loadStep(file);
  throw ModelError(file.string() + ": unknown kind of model file \"" + ext + "\" (expected .stl, .step or .stp)");
}

}  // namespace stampscan::acquisition
