// The cell's part programs as the operator's panel lists, shows and scans them: its library's, and
// on a virtual cell its own simulated parts (written on first use). A scan of a program puts its
// simulated part on the virtual fixture (when the cell is hosted; its truth scores the scan); a scan
// of the panel's own plan puts the world's part back.
#pragma once

#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/hmi/cell_jobs.hpp"
#include "virtual_cell/virtual_cell_host.hpp"

#include <cstdint>
#include <filesystem>

namespace stampscan::station {

// `host`: the virtual cell when hosted here (null otherwise); `seed`: the calibration scenes' (the
// panel's sessions are quick ones, with half the cell's scenes).
hmi::CellPrograms panelPrograms(const acquisition::CellConfig& config, bool virtual_cell,
                                const std::filesystem::path& runs, std::uint64_t seed, VirtualCellHost* host);

}  // namespace stampscan::station
