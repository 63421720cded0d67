// One printed grid element, however often it was measured. The laser's overlapping sweeps find
// most elements twice, and each stereo view finds them again: a few hundredths of a millimetre
// apart, with strains that differ by the measurements' noise. Downstream (the strain field over
// the surface, the report) these are one element, never a spacing of a few micrometres.
//
// Each sensor path's uncertainty is estimated from the scan itself, in two parts. Measurements of
// the same element by the same path (two overlapping sweeps, two stereo views) differ by the part
// of their error each has of its own; the spread of such twins gives its variance, as a function
// of the measurement's quality (GridElement::fit_rms): a + b q^2, for a ring seen obliquely or a
// cell whose corners stray from their affine image reads its strain worse. Part of a
// path's error is shared by all its measurements of one element (the same printed shape read the
// same way, the same calibration): twins cannot see it, but the laser and the stereo views measure
// each element in wholly different ways, so their disagreement shows the two paths' whole errors;
// what it holds beyond their own parts is taken as shared, half to each path. The merged element is
// the inverse-variance weighted mean of its paths' means, with the combined standard uncertainty.
// A measurement far from three or more of its own path's measurements of the element is a misreading
// and left out; one path's agreeing measurements do not outvote the other path (they share an error).
#pragma once

#include "stampscan/registration/grid_element.hpp"

#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

namespace stampscan::registration {

// The standard (k = 1) uncertainty of one measurement by a sensor path of the path's median quality,
// and of it the part shared by all that path's measurements of one element (which repeating them
// does not reduce; not known when no element was measured by both paths, and then not in the
// uncertainty).
struct PathNoise {
  std::optional<double> strain, strain_shared;            // thickness true strain
  std::optional<double> position_mm, position_shared_mm;  // along each axis
  std::size_t twin_pairs = 0;                             // same-path pairs of measurements
};

struct MergedElements {
  std::vector<GridElement> elements;      // one per printed element, with strain_sigma and position_sigma_mm
  std::vector<std::uint32_t> element_of;  // for each measurement, the index of its element
  // For each measurement, its standard uncertainties (NaN while its path's noise is not known).
  std::vector<double> strain_sigma_of, position_sigma_mm_of;
  PathNoise laser, stereo;
  std::size_t measurements = 0;
};

// Measurements closer than `twin_radius_mm` (a quarter of the grid's pitch is safe: neighbouring
// elements stand a pitch apart, stretched or compressed by at most a few tens of percent) are one
// element. The result does not depend on the order of the measurements.
MergedElements mergeMeasurements(const std::vector<GridElement>& measurements, double twin_radius_mm);

// Every measurement's strains moved from the mean over its outline to its element's centre: less
// its gauge_mm2 times the strain's Laplacian over the printed grid (grid_element.hpp), taken from a
// quadratic through the merged element and its neighbours (those within 1.6 pitches on the printed
// grid, `pitch_mm`). Where the strain bends, over a die radius or at a peak, the mean is lower than
// the peak and higher than the valley by up to a few thousandths of strain; the laser's rings and
// the stereo views' cells average over different outlines and so disagree there too. An element
// without neighbours on both sides along both axes (at the grid's edge) keeps its mean. Merge the
// measurements again afterwards. Returns how many measurements were moved.
std::vector<GridElement> strainsAtCentres(const std::vector<GridElement>& measurements, const MergedElements& merged,
                                          double pitch_mm);

// The merged elements that cannot be printed elements: one whose outline (the ellipse of its
// semi-axes in its tangent plane) holds another element's centre, or whose centre lies within
// another's outline, and which has fewer measurements than that other (the same: the noisier one). A stereo match across
// two cells measures a cell twice the size halfway between two true ones. Sorted indices.
std::vector<std::uint32_t> overlappingElements(const MergedElements& merged);

// What the measurements' noise leaves out of the merged elements' strain uncertainty, from the field
// around each (the same quadratic): how far its neighbours' strains stray from a smooth field beyond
// their own noise (a sheet that bends within a pitch, a reading error neighbours share), and the
// shift to the centre, known to no better than its own size (the Laplacian from neighbours a pitch
// apart). Each element's strain_sigma grows by both, in quadrature; an element at the grid's edge
// keeps its own.
void addFieldUncertainty(MergedElements& merged, double pitch_mm);

}  // namespace stampscan::registration
