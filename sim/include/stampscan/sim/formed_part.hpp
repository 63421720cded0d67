// A flat blank, printed with a grid, formed into a 3D part by a smooth deformation known in closed
// form. Every point of the formed (printed) surface knows where it was on the flat blank, so the
// deformation gradient, and from it the true major, minor and thickness strain, is known everywhere.
//
// Coordinates: material points m = (u, v) in millimetres on the flat blank; the formed part lies in
// the machine frame (millimetres, z up) as a height field z = height(x, y) over the table. Strains
// are those of the printed surface, the one the cameras and the digitizer see (membrane strain; the
// bending strain of the sheet is not modelled).
#pragma once

#include "stampscan/fitting/cloud.hpp"
#include "stampscan/sim/sample_part.hpp"

#include <Eigen/Core>

#include <memory>
#include <string>
#include <vector>

namespace stampscan::sim {

using fitting::Vec3;
using Vec2 = Eigen::Vector2d;

// The deformation at one point of the part.
struct Deformation {
  Vec3 point;                       // on the formed surface, machine frame
  Vec3 normal;                      // unit, facing +z
  Vec2 material;                    // where the point was on the flat blank
  Eigen::Matrix<double, 3, 2> gradient;  // F = dX/d(u, v)
  double major_stretch = 1, minor_stretch = 1;  // principal stretches, major >= minor
  double major_strain = 0, minor_strain = 0;    // true strains eps1 = ln(major), eps2 = ln(minor)
  double thickness_strain = 0;                  // eps3 = -(eps1 + eps2): volume constancy
  Vec3 major_direction;             // unit, tangent to the formed surface
  Vec2 major_direction_material;    // unit, on the blank: the printed circle's axis that becomes major
};

// An axis-aligned rectangle of material coordinates.
struct BlankRect {
  Vec2 min, max;
  bool contains(const Vec2& m) const { return (m.array() >= min.array()).all() && (m.array() <= max.array()).all(); }
};

class FormedPart {
 public:
  virtual ~FormedPart() = default;
  virtual std::string name() const = 0;
  // Height of the formed surface over machine (x, y); the blank's flat flange is at z = 0.
  virtual double height(double x, double y) const = 0;
  // The material point of the blank that came to lie at machine (x, y): the inverse of the in-plane
  // part of the forming map. Defined for every (x, y); it lies on the blank when onPart(x, y).
  virtual Vec2 materialAt(double x, double y) const = 0;
  // The blank before forming.
  virtual BlankRect blank() const = 0;
  // Machine-frame xy box that holds the whole formed part.
  virtual BlankRect footprint() const = 0;
  // Height range of the formed surface.
  virtual double minHeight() const = 0;
  virtual double maxHeight() const = 0;

  bool onPart(double x, double y) const { return blank().contains(materialAt(x, y)); }
  Vec3 surfacePoint(double x, double y) const { return {x, y, height(x, y)}; }
  Vec3 normal(double x, double y) const;
  // Where material point m lies after forming (Newton on materialAt).
  Vec3 position(const Vec2& m) const;
  // The deformation at machine (x, y), or at material point m.
  Deformation deformationAt(double x, double y) const;
  Deformation deformationOfMaterial(const Vec2& m) const { const Vec3 p = position(m); return deformationAt(p.x(), p.y()); }
  Vec3 closestPoint(const Vec3& p) const;
  double distance(const Vec3& p) const { return (p - closestPoint(p)).norm(); }
};

// A punch-stretched dome, as in the paper's test domes: the blank is clamped at the die radius and
// a round punch stretches it into a smooth dome. The pole is stretched equibiaxially
// (exp(pole_strain) in both directions); the strain falls to zero at the die, and the wall adds
// meridional stretch where it is steep.
struct DomeParams {
  double blank_half_size = 75;  // mm, the square blank is 2x this
  double die_radius = 55;       // mm, the sheet is flat (and clamped) beyond
  double depth = 30;            // mm, pole height above the flange
  double pole_strain = 0.12;    // equibiaxial true strain at the pole
};

class DomePart final : public FormedPart {
 public:
  explicit DomePart(const DomeParams& params = {});
  std::string name() const override { return "dome"; }
  double height(double x, double y) const override;
  Vec2 materialAt(double x, double y) const override;
  BlankRect blank() const override;
  BlankRect footprint() const override { return blank(); }  // the flange does not move
  double minHeight() const override { return 0; }
  double maxHeight() const override { return params_.depth; }
  const DomeParams& params() const { return params_; }

 private:
  DomeParams params_;
};

// A stamped rectangular pan: a flange, walls around a rounded-rectangle pocket, and a small dome in
// its floor (the height field of PanPart). The material is drawn into the pocket: the flange shrinks
// circumferentially (negative minor strain, thickening), and the wall is stretched most just above
// the punch radius, where a band of high strain peaks at about `peak_strain`.
struct StampedPanParams {
  double half_length = 80, half_width = 60;  // mm, formed footprint
  double pocket_a = 45, pocket_b = 32;       // mm, pocket half-sizes at mid-wall
  double depth = 20;                         // mm
  double wall_width = 22;                    // mm, horizontal run of the wall: punch and die radii of about 4 mm
  double dome_radius = 12, dome_height = 4;  // mm, dome in the pocket floor
  double peak_strain = 0.3;                  // meridional true strain at the band above the punch radius
};

class StampedPanPart final : public FormedPart {
 public:
  explicit StampedPanPart(const StampedPanParams& params = {});
  std::string name() const override { return "pan"; }
  double height(double x, double y) const override;
  Vec2 materialAt(double x, double y) const override;
  BlankRect blank() const override { return blank_; }
  BlankRect footprint() const override;
  double minHeight() const override { return -params_.depth; }
  double maxHeight() const override { return 0; }
  const StampedPanParams& params() const { return params_; }

 private:
  // Material "radius" sigma of the pocket-shaped level set at formed radius s (both normalised so
  // that s = 1 is the pocket outline): sigma(s) = integral of sqrt(1 + z'^2) / lambda_m.
  double materialRadius(double s) const;

  StampedPanParams params_;
  PanPart shape_;  // the formed height field
  double table_step_ = 0;
  std::vector<double> stretch_;  // integrand samples
  std::vector<double> sigma_;    // cumulative integral at the samples
  BlankRect blank_;
};

enum class PartKind { Dome, Pan };
std::unique_ptr<FormedPart> makePart(PartKind kind);

}  // namespace stampscan::sim
