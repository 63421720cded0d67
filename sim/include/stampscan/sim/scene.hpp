// What the sensors look at: the formed part with its printed grid, the calibration plate and the
// reference sphere, each on the table. A scene answers one question for a ray: where does it hit
// first, with which normal, and how much light does the surface send back there.
#pragma once

#include "stampscan/sim/formed_part.hpp"
#include "stampscan/sim/grid.hpp"

#include <Eigen/Geometry>

#include <optional>

namespace stampscan::sim {

struct Ray {
  Vec3 origin;
  Vec3 direction;  // unit
};

struct Hit {
  double t = 0;      // distance along the ray, mm
  Vec3 point;
  Vec3 normal;       // unit, facing the ray's origin side of the surface
  double albedo = 0; // diffuse reflectance 0..1, box-filtered over the footprint
  bool shiny = false;  // a polished spot: the digitizer sees glare there
};

class Scene {
 public:
  virtual ~Scene() = default;
  // The first hit along the ray. `footprint_per_mm` is the width of the sensor's sample footprint
  // per millimetre of distance (pixel or laser-spot angular size), used to box-filter the albedo.
  // `t_hint`, when positive, is the hit distance of a neighbouring ray: a start for the search.
  virtual std::optional<Hit> cast(const Ray& ray, double footprint_per_mm, double t_hint = -1) const = 0;
};

// The table the scenes stand on: a dark matte plane at z = table_z.
struct Table {
  double z = -60;
  double albedo = 0.08;
};

// The formed part with its grid; the flange rests on a fixture above the table. The part is modelled
// in its datum frame; `machine_from_datum` is where the fixture holds that frame (the cell file's
// [fixture]). Rays and hits are in the machine frame.
class PartScene final : public Scene {
 public:
  PartScene(const FormedPart& part, const GridSpec& grid, const Eigen::Isometry3d& machine_from_datum = Eigen::Isometry3d::Identity(),
            Table table = {});
  std::optional<Hit> cast(const Ray& ray, double footprint_per_mm, double t_hint = -1) const override;
  const FormedPart& part() const { return part_; }
  const GridSpec& grid() const { return grid_; }
  const Eigen::Isometry3d& machineFromDatum() const { return machine_from_datum_; }
  // Diffuse reflectance of the coated sheet, and of the printed ink.
  static constexpr double kSheetAlbedo = 0.75, kInkAlbedo = 0.10;

 private:
  std::optional<Hit> castOnPart(const Ray& ray_in_datum, double footprint_per_mm, double t_hint) const;

  const FormedPart& part_;
  GridSpec grid_;
  BlankRect printed_;
  Eigen::Isometry3d machine_from_datum_, datum_from_machine_;
  bool at_origin_ = true;
  Table table_;
  double max_slope_ = 1;  // bound on |grad h|, for the safe marching step
  BlankRect footprint_;    // the part's footprint grown by a millimetre: rays beside it miss it
};

// A flat calibration plate with a symmetric grid of black dots on white, at a pose on the table.
struct CirclePlate {
  int columns = 9, rows = 7;   // dots; odd counts keep the pattern's orientation unambiguous
  double pitch = 6;            // mm between dot centres
  double dot_diameter = 3;     // mm
  double margin = 6;           // mm of white around the outer dots
  // Dot (i, j) is at (i * pitch, j * pitch, 0) in the plate frame; the plate faces +z.
  Vec3 dotCentre(int i, int j) const { return {i * pitch, j * pitch, 0}; }
};

class PlateScene final : public Scene {
 public:
  PlateScene(const CirclePlate& plate, const Eigen::Isometry3d& machine_from_plate, Table table = {});
  std::optional<Hit> cast(const Ray& ray, double footprint_per_mm, double t_hint = -1) const override;

 private:
  CirclePlate plate_;
  Eigen::Isometry3d machine_from_plate_, plate_from_machine_;
  Table table_;
};

// A matte reference sphere (the digitizer's calibration artefact) on a stem above the table.
struct ReferenceSphere {
  Vec3 centre{250, 0, 40};
  double radius = 12.7;  // mm, a one-inch ball
  double albedo = 0.6;
};

class SphereScene final : public Scene {
 public:
  explicit SphereScene(const ReferenceSphere& sphere, Table table = {});
  std::optional<Hit> cast(const Ray& ray, double footprint_per_mm, double t_hint = -1) const override;

 private:
  ReferenceSphere sphere_;
  Table table_;
};

}  // namespace stampscan::sim
