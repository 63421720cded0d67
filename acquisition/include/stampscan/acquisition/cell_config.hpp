// The cell configuration: where each device of the cell is, and what its machine can do. A TOML
// file (station/cells/virtual.toml describes the virtual cell and is the default), read with toml++;
// errors name the file, the key and what is wrong.
#pragma once

#include "stampscan/acquisition/scan_plan.hpp"

#include <cstdint>
#include <filesystem>
#include <string>

namespace stampscan::acquisition {

// The cell's calibration rules ([calibration]): where the calibration in use and its history are
// kept, how long a calibration stays valid, what a new one must reach to be put in use, how far it
// may move from the one in use before that is reported as drift, and the reference sphere's
// certificate with the maximum permissible errors of `station verify`. The defaults suit the
// virtual cell's sensors; a real cell's file gives its manufacturer's figures.
struct CalibrationPolicy {
  std::string dir;                        // "" : the calibration folder beside the runs (<runs>/calibration)
  double validity_days = 7;               // a scan refuses a calibration older than this
  // Acceptance limits of a new calibration (every figure at or below its limit).
  double digitizer_residual_mm = 0.015;   // radial RMS of the sphere sweeps about the fitted sphere
  double camera_reprojection_px = 0.25;   // reprojection RMS of each camera and of the pair
  double head_mount_residual_mm = 0.05;   // the plate's implied machine position, RMS over the views
  // Drift: a new calibration that moves this far from the one in use is reported.
  double drift_mount_mm = 0.05;           // the digitizer's or the cameras' mount on the head
  double drift_latency_ms = 0.2;          // the digitizer's latency
  double drift_baseline_mm = 0.05;        // the stereo pair's baseline
  // The reference sphere: its certified diameter (0: the cell description's) and the verification's
  // maximum permissible errors (ISO 10360-8 probing form and size).
  double sphere_diameter_mm = 0;
  double form_mpe_mm = 0.100, size_mpe_mm = 0.030;
  // The ball bar: a second sphere (its certified diameter) at a certified centre distance from the
  // reference sphere, for the length check of `station verify`; a distance of 0 means the cell has
  // none. The MPE of the length measurement error.
  double second_sphere_diameter_mm = 0, sphere_distance_mm = 0;
  double length_mpe_mm = 0.050;
  // The stereo pair's MPEs on the calibration plate's dots (flat form, length between dots).
  double stereo_form_mpe_mm = 0.050, stereo_length_mpe_mm = 0.050;
};

struct CellConfig {
  std::string name = "virtual cell";
  std::string source;  // the file it came from, or "built-in"
  struct Endpoint {
    std::string host = "127.0.0.1";
    int port = 0;
  };
  Endpoint cmm{"127.0.0.1", 1294};
  // The machine's travel, speeds and head angles ([machine]): a plan outside them is refused
  // before anything moves. The defaults are the virtual CMM's.
  MachineLimits limits;
  // The CMM stamps its move reports with its own clock (the SS.Time() extension of
  // drivers/cmm/PROTOCOL.md): positions are then timed by the CMM, not by their arrival.
  bool cmm_device_time = false;
  Endpoint plc{"127.0.0.1", 1502};
  int plc_unit_id = 1;
  struct Camera {
    std::string serial, address;
  };
  Camera left_camera{"STAMPSCAN-LEFT", "127.0.0.1"}, right_camera{"STAMPSCAN-RIGHT", "127.0.0.2"};
  std::uint16_t digitizer_vendor = 0x1d50, digitizer_product = 0x61a5;
  std::string digitizer_serial;
  // The virtual digitizer is a USB device under umockdev (sim/virtual_digitizer): it exists only
  // inside the process that hosts it, so no server can offer it to others. A cell that marks its
  // digitizer virtual has `station devices` host it in its own process (virtual_digitizer_host.hpp).
  bool digitizer_virtual = false;
  bool digitizer_required = true;
  CalibrationPolicy calibration;
  // The results database ([results] database): a runs folder (its results.sqlite) or a PostgreSQL
  // URL when several cells write to one place. Empty: the runs folder of each command.
  std::string results_database;
  // The plant's own materials ([report] materials): a material library file (station/materials.toml's
  // format) whose entries are added to, or replace, the built-in ones. A path relative to the cell
  // file is taken from the cell file's folder. Empty: the built-in library alone.
  std::string materials_file;
};

// The built-in virtual cell (the same as station/cells/virtual.toml).
CellConfig virtualCell();
// Throws std::runtime_error naming the file and the key.
CellConfig loadCellConfig(const std::filesystem::path& file);

}  // namespace stampscan::acquisition
