// The cell's devices as the station drives them: one driver per device, built from the cell config,
// the same for a real cell and the virtual one (only the addresses differ). A Cell owns its drivers;
// the ScanRunner and `station devices` borrow them. Destroying it disconnects them.
#pragma once

#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/acquisition/scan_runner.hpp"
#include "stampscan/drivers/camera/gige_camera.hpp"
#include "stampscan/drivers/cmm/ipp_client.hpp"
#include "stampscan/drivers/digitizer/usb_digitizer.hpp"
#include "stampscan/drivers/plc/modbus_plc.hpp"

#include <memory>

namespace stampscan::acquisition {

// What the drivers are built for.
enum class CellUse {
  Session,  // a scan, calibration or verification: the PLC's watchdog heartbeat, cameras that reconnect
  Check,    // a look at the devices (`station devices`, the panel's cell view): no heartbeat for the
            // PLC's watchdog to see start, no reconnecting, and a CMM that does not answer given up in 1.5 s
};

class Cell {
 public:
  // Builds the drivers (nothing is connected yet). Throws std::invalid_argument for a config the
  // drivers refuse.
  explicit Cell(const CellConfig& config, CellUse use = CellUse::Session);
  ~Cell();
  Cell(const Cell&) = delete;
  Cell& operator=(const Cell&) = delete;

  const CellConfig& config() const { return config_; }
  drivers::cmm::IppCmm& cmm() { return *cmm_; }
  drivers::plc::ModbusPlc& plc() { return *plc_; }
  drivers::digitizer::UsbDigitizer& digitizer() { return *digitizer_; }
  drivers::camera::GigECamera& leftCamera() { return *left_camera_; }
  drivers::camera::GigECamera& rightCamera() { return *right_camera_; }
  CellDevices devices() { return {*cmm_, *plc_, *digitizer_, left_camera_.get(), right_camera_.get()}; }

 private:
  CellConfig config_;
  std::unique_ptr<drivers::cmm::IppCmm> cmm_;
  std::unique_ptr<drivers::plc::ModbusPlc> plc_;
  std::unique_ptr<drivers::digitizer::UsbDigitizer> digitizer_;
  std::unique_ptr<drivers::camera::GigECamera> left_camera_, right_camera_;
};

}  // namespace stampscan::acquisition
