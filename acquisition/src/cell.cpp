#include "stampscan/acquisition/cell.hpp"

#include <algorithm>
#include <cmath>
#include <tuple>

namespace stampscan::acquisition {

Cell::Cell(const CellConfig& config, CellUse use) : config_(config) {
  const bool check = use == CellUse::Check;
  drivers::cmm::IppCmmOptions cmm;
  cmm.host = config.cmm.host;
  cmm.port = static_cast<std::uint16_t>(config.cmm.port);
  cmm.device_time_in_reports = config.cmm_device_time;
  if (check) cmm.connect_timeout = std::chrono::milliseconds(1500);
  cmm_ = std::make_unique<drivers::cmm::IppCmm>(cmm);
  drivers::plc::ModbusPlcOptions plc;
  plc.host = config.plc.host;
  plc.port = config.plc.port;
  plc.unit_id = config.plc_unit_id;
  plc.registers = config.plc_registers;
  plc.watchdog = !check;
  plc_ = std::make_unique<drivers::plc::ModbusPlc>(plc);
  drivers::digitizer::UsbDigitizerOptions digitizer;
  digitizer.vendor_id = config.digitizer_vendor;
  digitizer.product_id = config.digitizer_product;
  digitizer.serial = config.digitizer_serial;
  // The digitizer runs as the cell file draws it (the plans' sweep speeds and the virtual twin
  // assume it): its points per profile and profile rate. The exposure stays the driver's, shortened
  // to the profile period at high rates.
  const DigitizerDrawing& drawn = config.geometry.digitizer;
  digitizer.config.points_per_profile = drawn.points_per_profile;
  digitizer.config.profile_rate_hz = drawn.profile_rate_hz;
  digitizer.config.exposure_us =
      std::min(digitizer.config.exposure_us, static_cast<std::uint32_t>(std::floor(1e6 / drawn.profile_rate_hz)));
  digitizer_ = std::make_unique<drivers::digitizer::UsbDigitizer>(digitizer);
  for (auto [camera, config_of, name] : {std::tuple{&left_camera_, &config.left_camera, "camera_l"},
                                         std::tuple{&right_camera_, &config.right_camera, "camera_r"}}) {
    drivers::camera::GigECameraOptions o;
    o.serial = config_of->serial;
    o.address = config_of->address;
    o.auto_reconnect = !check;
    *camera = std::make_unique<drivers::camera::GigECamera>(name, o);
  }
}

Cell::~Cell() {
  // The digitizer first: its event thread may still deliver into a sink the caller owns.
  digitizer_->disconnect();
  left_camera_->disconnect();
  right_camera_->disconnect();
  plc_->disconnect();
  cmm_->disconnect();
}

}  // namespace stampscan::acquisition
