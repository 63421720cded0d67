// A third-party Modbus client (mbpoll) against the virtual PLC: the registers are where the standard
// map says, for any Modbus tool, not just for our own driver. Skipped with a reason without mbpoll.
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <sstream>

#include "plc_test_support.hpp"

namespace stampscan::plc_test {
namespace {

using drivers::plc::Coil;
using drivers::plc::DiscreteInput;
using drivers::plc::HoldingRegister;
using drivers::plc::InputRegister;
using drivers::plc::ModbusPlc;

std::string findInPath(const std::string& program) {
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path != nullptr ? path : "/usr/bin:/bin");
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    const std::string candidate = (dir.empty() ? "." : dir) + "/" + program;
    if (::access(candidate.c_str(), X_OK) == 0) return candidate;
  }
  return "";
}

struct MbpollResult {
  int exit_status = -1;
  std::string output;
  std::map<int, long> values;  // reference -> value, from lines like "[3]: 	42"
};

class PlcMbpollTest : public PlcFixture {
 protected:
  void SetUp() override {
    mbpoll_ = findInPath("mbpoll");
    if (mbpoll_.empty())
      GTEST_SKIP() << "mbpoll is not installed (apt-get install mbpoll); the check with a "
                      "third-party Modbus client is skipped";
    PlcFixture::SetUp();
  }

  // One mbpoll run, PDU addressing (-0), one poll (-1), 1 s timeout; `args` picks table and range.
  MbpollResult run(const std::string& args) const {
    const std::string command = "timeout 10 " + mbpoll_ + " -m tcp -a 1 -p " +
                                std::to_string(plc_.port()) + " -0 -1 -o 1 " + args + " 2>&1";
    MbpollResult result;
    FILE* pipe = ::popen(command.c_str(), "r");
    if (pipe == nullptr) return result;
    std::array<char, 512> buffer{};
    while (std::fgets(buffer.data(), static_cast<int>(buffer.size()), pipe) != nullptr)
      result.output += buffer.data();
    result.exit_status = ::pclose(pipe);
    // No std::regex: GCC 12 warns (maybe-uninitialized) inside it under the sanitizers.
    std::istringstream lines(result.output);
    std::string line;
    while (std::getline(lines, line)) {
      int reference = 0;
      long value = 0;
      char close = 0;
      char colon = 0;
      std::istringstream fields(line);
      if (fields.get() == '[' && fields >> reference >> close >> colon >> value && close == ']' &&
          colon == ':')
        result.values[reference] = value;
    }
    return result;
  }

  std::string mbpoll_;
};

// The standard map's address of a signal.
template <class Signal>
int address(Signal signal) {
  return drivers::plc::RegisterMap::standard().address(signal);
}

TEST_F(PlcMbpollTest, ReadsTheMappedRegisters) {
  const MbpollResult inputs = run("-t 3 -r 0 -c 6 127.0.0.1");
  ASSERT_EQ(inputs.exit_status, 0) << inputs.output;
  ASSERT_EQ(inputs.values.size(), 6U) << inputs.output;
  EXPECT_EQ(inputs.values.at(address(InputRegister::FirmwareMajor)), 1) << inputs.output;
  EXPECT_EQ(inputs.values.at(address(InputRegister::FirmwareMinor)), 0) << inputs.output;
  EXPECT_EQ(inputs.values.at(address(InputRegister::InterlockState)), 0) << inputs.output;

  plc_.openDoor();
  const MbpollResult bits = run("-t 1 -r 0 -c 6 127.0.0.1");
  ASSERT_EQ(bits.exit_status, 0) << bits.output;
  EXPECT_EQ(bits.values.at(address(DiscreteInput::DoorClosed)), 0) << bits.output;
  EXPECT_EQ(bits.values.at(address(DiscreteInput::EStopChainOk)), 1) << bits.output;
  EXPECT_EQ(bits.values.at(address(DiscreteInput::LaserShutterClosed)), 1) << bits.output;
  const MbpollResult faults = run("-t 3 -r 4 -c 2 127.0.0.1");
  EXPECT_EQ(faults.values.at(address(InputRegister::FaultWord)), 1) << faults.output;  // door_open
  EXPECT_EQ(faults.values.at(address(InputRegister::InterlockState)), 1) << faults.output;

  const MbpollResult holding = run("-t 4 -r 1 -c 1 127.0.0.1");
  EXPECT_EQ(holding.values.at(address(HoldingRegister::WatchdogTimeoutMs)), 1000) << holding.output;
}

TEST_F(PlcMbpollTest, WritesACoil) {
  const MbpollResult written = run("-t 0 -r 1 127.0.0.1 1");  // stack_light_amber := 1
  ASSERT_EQ(written.exit_status, 0) << written.output;
  EXPECT_TRUE(plc_.coil(Coil::StackLightAmber));
  EXPECT_FALSE(plc_.coil(Coil::StackLightGreen));
}

TEST_F(PlcMbpollTest, PlaysTheLinesSideOfTheHandshake) {
  // As REGISTER_MAP.md shows it: the program number and the part id "P-0001" (two characters a
  // register, the first in the high byte), then the start request.
  const MbpollResult program = run("-t 4 -r 3 127.0.0.1 7 0x502D 0x3030 0x3031");
  ASSERT_EQ(program.exit_status, 0) << program.output;
  const MbpollResult start = run("-t 4 -r 2 127.0.0.1 1");
  ASSERT_EQ(start.exit_status, 0) << start.output;
  ModbusPlc driver(options());
  driver.connect();
  const drivers::plc::LineRequest request = driver.readLineRequest();
  EXPECT_TRUE(request.start);
  EXPECT_EQ(request.program_number, 7);
  EXPECT_EQ(request.part_id, "P-0001");

  // The cell's answer, as the line reads it: cell_ready .. cell_error_code from 20.
  driver.writeCellAnswer({false, false, true, drivers::plc::LineVerdict::Marginal, drivers::plc::LineError::None});
  const MbpollResult answer = run("-t 4 -r 20 -c 5 127.0.0.1");
  ASSERT_EQ(answer.exit_status, 0) << answer.output;
  EXPECT_EQ(answer.values.at(address(HoldingRegister::CellReady)), 0) << answer.output;
  EXPECT_EQ(answer.values.at(address(HoldingRegister::CellDone)), 1) << answer.output;
  EXPECT_EQ(answer.values.at(address(HoldingRegister::CellVerdict)), 2) << answer.output;
  EXPECT_EQ(answer.values.at(address(HoldingRegister::CellErrorCode)), 0) << answer.output;
  driver.disconnect();
}

}  // namespace
}  // namespace stampscan::plc_test
