// The cell file: everything the station knows about one cell. Where each device is and how to reach
// it, what the machine and its head can do, the sensors, artefacts and fixture as drawn
// (cell_geometry.hpp), the calibration rules, the results database and the report's materials. A
// TOML file (station/cells/virtual.toml describes the virtual cell and is the default), read with
// toml++; every value is checked when read, and an error names the file, the section and the key.
#pragma once

#include "stampscan/acquisition/cell_geometry.hpp"
#include "stampscan/acquisition/scan_plan.hpp"
#include "stampscan/drivers/plc/plc_register_map.hpp"

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

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
  // The verification's maximum permissible errors on the reference sphere (ISO 10360-8 probing form
  // and size) and of the length measurement error on the ball bar (the artefacts' certificates are
  // in the cell's geometry: [sphere], [ball_bar]).
  double form_mpe_mm = 0.100, size_mpe_mm = 0.030;
  double length_mpe_mm = 0.050;
  // The stereo pair's MPEs on the calibration plate's dots (flat form, length between dots).
  double stereo_form_mpe_mm = 0.050, stereo_length_mpe_mm = 0.050;
  // The calibration scenes (calibration_plan.hpp): the views of the plate and the sweeps over the
  // reference sphere that `station calibrate` runs (a scan with calibration scenes runs them too,
  // a quick one half of them), and the sweeps over the ball bar's second sphere that `station
  // verify` adds.
  int plate_views = 12, sphere_sweeps = 8, ball_bar_sweeps = 4;
};

struct CellConfig {
  std::string name = "virtual cell";
  std::string source;  // the file it came from, or "built-in"
  struct Endpoint {
    std::string host = "127.0.0.1";
    int port = 0;
  };
  Endpoint cmm{"127.0.0.1", 1294};
  // The machine's travel and speeds ([machine]) and its head's angles, turning and index step
  // ([head]): a plan outside them is refused before anything moves. The defaults are the virtual CMM's.
  MachineLimits limits;
  // The head's kind and body, the sensors, the artefacts and the fixture as drawn.
  CellGeometry geometry;
  // The CMM stamps its move reports with its own clock (the SS.Time() extension of
  // drivers/cmm/PROTOCOL.md): positions are then timed by the CMM, not by their arrival.
  bool cmm_device_time = false;
  Endpoint plc{"127.0.0.1", 1502};
  int plc_unit_id = 1;
  // Where the PLC program puts each signal ([plc.registers], by the names of
  // drivers/plc/REGISTER_MAP.md): the driver reads and writes there, and the cell's virtual twin
  // serves there. Default: the standard map.
  drivers::plc::RegisterMap plc_registers;
  // [plc] line_start: the line's PLC may start scans through the handshake registers (line_* and
  // cell_* of REGISTER_MAP.md), which `station hmi` then watches. Off: those registers are left alone
  // (a PLC program without them is not read there).
  bool plc_line_start = false;
  struct Camera {
    std::string serial, address;
  };
  Camera left_camera{"STAMPSCAN-LEFT", "127.0.0.1"}, right_camera{"STAMPSCAN-RIGHT", "127.0.0.2"};
  std::uint16_t digitizer_vendor = 0x1d50, digitizer_product = 0x61a5;
  std::string digitizer_serial;
  // The virtual digitizer is a USB device under umockdev (sim/virtual_digitizer): it exists only
  // inside the process that hosts it, so no server can offer it to others. A cell that marks its
  // digitizer virtual has `station devices` host it in its own process (station/src/virtual_cell/virtual_digitizer_host.hpp).
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
  // The cell's program library ([programs] library): a folder of part programs (part_program.hpp),
  // one folder each. A path relative to the cell file is taken from its folder. Empty: none given.
  std::string program_library;
  // The operator's panel ([hmi]): where `station hmi` listens, who may log in, and the TLS front
  // (Debian's nginx, configured by `station hmi --front-config`) that serves it on the plant's network.
  struct Panel {
    std::string listen = "127.0.0.1:8080";  // HOST:PORT of the panel itself
    std::string users_file;                 // [hmi] users; relative to the cell file's folder
    // The names the plant's network reaches the panel under (besides loopback): any other Host is
    // refused, so that a web page cannot reach the panel through a name of its own (DNS rebinding).
    std::vector<std::string> server_names;
    // The front's certificate and key (PEM); set, the panel is served through its TLS front: it
    // listens on loopback behind it and every user logs in.
    std::string tls_certificate, tls_key;
    int https_port = 443, http_port = 80;  // the front's; plain HTTP is redirected to HTTPS
    bool behindTlsFront() const { return !tls_certificate.empty(); }
  };
  Panel panel;
  // The keys the file left out, which took their default ("[digitizer] latency_ms"), for
  // `station cell check`; empty for the built-in cell.
  std::vector<std::string> defaulted;
};

// [hmi]'s rules for what goes into the TLS front's configuration (hmi/tls_front.hpp): a server
// name is a host name or an IPv4 address (letters, digits, '.' and '-'); a certificate or key
// path holds no quote, '$', ';', brace, backslash or control character (it is written quoted).
bool isServerName(const std::string& name);
bool isQuotablePath(const std::string& path);

// The built-in virtual cell (the same as station/cells/virtual.toml).
CellConfig virtualCell();
// Throws std::runtime_error naming the file, the section and the key.
CellConfig loadCellConfig(const std::filesystem::path& file);
// The whole cell as understood, one line per value, in the cell file's sections and units; values
// that came from defaults are marked. What `station cell check` prints.
std::string describeCellConfig(const CellConfig& cell);

}  // namespace stampscan::acquisition
