// `station devices [--cell CELL.toml] [--virtual]`: finds every device of the cell, checks it, and
// prints a table of identity, address, firmware, state and faults. Exit 0 when every required
// device answered and reports no fault; 1 otherwise. With --virtual the cell file's virtual twin is
// hosted in this process first; otherwise a cell whose digitizer is virtual has that hosted
// (virtual_cell/virtual_digitizer_host.hpp). Hosting may re-execute the program under umockdev.
#include "stampscan/drivers/camera/gige_camera.hpp"
#include "stampscan/drivers/cmm/ipp_client.hpp"
#include "stampscan/drivers/digitizer/usb_digitizer.hpp"
#include "stampscan/drivers/plc/modbus_plc.hpp"
#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/acquisition/cell.hpp"
#include "stampscan/station/commands.hpp"
#include "cell_choice.hpp"
#include "virtual_cell/virtual_cell_host.hpp"

#include <algorithm>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

namespace stampscan::station {

using acquisition::CellConfig;

namespace {

struct Row {
  std::string device, address, identity, firmware, state, faults;
  bool ok = false, required = true;
};

Row probe(drivers::Device& device, const std::string& address, bool required) {
  Row row;
  row.device = device.name();
  row.address = address;
  row.required = required;
  try {
    device.connect();
    const drivers::DeviceIdentity id = device.identity();
    row.identity = id.vendor.empty() ? id.model : id.vendor + " " + id.model;
    if (!id.serial.empty()) row.identity += " #" + id.serial;
    row.firmware = id.firmware.empty() ? "-" : id.firmware;
    row.ok = device.check();
  } catch (const std::exception& e) {
    row.identity = "-";
    row.firmware = "-";
    row.faults = e.what();
  }
  row.state = drivers::toString(device.state());
  for (const drivers::DeviceFault& f : device.faults())
    if (row.faults.find(f.text) == std::string::npos) row.faults += (row.faults.empty() ? "" : "; ") + f.code + ": " + f.text;
  device.disconnect();
  if (row.faults.empty()) row.faults = "-";
  return row;
}

}  // namespace

CommandRunner addDevicesCommand(CLI::App& app) {
  auto choice = std::make_shared<CellChoice>();
  CLI::App* cmd = app.add_subcommand("devices", "Find and check every device of the cell; a table of their identity and state");
  choice->addTo(cmd, false);
  return [choice]() {
    // Unlike the commands that run the cell, the built-in virtual cell is not hosted unless asked
    // for: `station devices` checks the cell that `station sim serve` serves.
    CommandCell command_cell = choice->open();
    command_cell.virtual_cell = choice->host_virtual;
    const CellConfig& cell = command_cell.config;
    // First of all: hosting may re-execute this program, and the device must be on the bus before
    // any libusb context exists (the cameras' Aravis makes one too).
    VirtualWorld world;
    world.quick = true;
    command_cell.simulate(world);
    command_cell.serve(true);
    std::shared_ptr<void> virtual_digitizer;
    if (!command_cell.host) virtual_digitizer = hostVirtualDigitizerOf(cell);
    std::printf("station devices: %s (%s)\n", cell.name.c_str(), cell.source.c_str());
    std::vector<Row> rows;
    // The same drivers a scan uses, built for a check (acquisition::CellUse::Check).
    acquisition::Cell devices(cell, acquisition::CellUse::Check);
    rows.push_back(probe(devices.cmm(), cell.cmm.host + ":" + std::to_string(cell.cmm.port), true));
    rows.push_back(probe(devices.plc(), cell.plc.host + ":" + std::to_string(cell.plc.port), true));
    for (const auto& [camera, config] : {std::pair{&devices.leftCamera(), cell.left_camera},
                                         std::pair{&devices.rightCamera(), cell.right_camera}})
      rows.push_back(probe(*camera, config.address.empty() ? "serial " + config.serial : config.address, true));
    char usb[32];
    std::snprintf(usb, sizeof usb, "usb %04x:%04x", cell.digitizer_vendor, cell.digitizer_product);
    rows.push_back(probe(devices.digitizer(), usb, cell.digitizer_required));
    // The identity and firmware columns widen to their longest entry, so that the table stays aligned.
    int identity_width = 28, firmware_width = 10;
    for (const Row& r : rows) {
      identity_width = std::max(identity_width, static_cast<int>(r.identity.size()));
      firmware_width = std::max(firmware_width, static_cast<int>(r.firmware.size()));
    }
    std::printf("  %-10s %-22s %-*s %-*s %-12s %s\n", "device", "address", identity_width, "identity", firmware_width,
                "firmware", "state", "faults");
    bool all_ok = true;
    for (const Row& r : rows) {
      std::printf("  %-10s %-22s %-*s %-*s %-12s %s%s\n", r.device.c_str(), r.address.c_str(), identity_width,
                  r.identity.c_str(), firmware_width, r.firmware.c_str(),
                  r.ok ? r.state.c_str() : (r.required ? "MISSING" : "absent"), r.faults.c_str(),
                  r.required || r.ok ? "" : " (optional in this cell)");
      if (r.required && !r.ok) all_ok = false;
    }
    if (command_cell.host) std::printf("  the cell is the virtual one, hosted in this process\n");
    if (virtual_digitizer) std::printf("  the digitizer is the virtual one, hosted in this process under umockdev\n");
    std::printf("  %s\n", all_ok ? "all required devices answered" : "a required device is missing or faulty");
    return all_ok ? 0 : 1;
  };
}

}  // namespace stampscan::station
