// The line's PLC starts scans: the panel (`station hmi` on the built-in virtual cell, whose cell file
// says [plc] line_start = true) watches the handshake registers of drivers/plc/REGISTER_MAP.md, and
// this test plays the line's side over Modbus TCP with libmodbus, as a line's PLC (or mbpoll) would.
#include "hmi_test_support.hpp"

#include "stampscan/drivers/plc/plc_register_map.hpp"

#include <modbus.h>

#include <cerrno>
#include <functional>

namespace stampscan::hmi::test {
namespace {

namespace plc = drivers::plc;

// The line's PLC: writes its request into the virtual cell's PLC and reads the cell's answer, at
// the standard map's addresses.
class LineSide {
 public:
  explicit LineSide(int port) : context_(modbus_new_tcp("127.0.0.1", port), &modbus_free) {
    if (!context_ || modbus_connect(context_.get()) != 0)
      throw std::runtime_error(std::string("the line's Modbus client: ") + modbus_strerror(errno));
    modbus_set_slave(context_.get(), 1);
  }
  ~LineSide() { modbus_close(context_.get()); }

  void request(std::uint16_t program_number, const std::string& part_id) {
    const auto id = plc::encodePartId(part_id);
    write(plc::HoldingRegister::LineProgramNumber, program_number);
    if (modbus_write_registers(context_.get(), map_.address(plc::HoldingRegister::LinePartId), plc::kPartIdRegisters,
                               id.data()) != plc::kPartIdRegisters)
      throw std::runtime_error(std::string("writing line_part_id: ") + modbus_strerror(errno));
    write(plc::HoldingRegister::LineStartRequest, 1);
  }
  void drop() { write(plc::HoldingRegister::LineStartRequest, 0); }

  plc::CellAnswer answer() {
    std::array<std::uint16_t, 5> regs{};
    if (modbus_read_registers(context_.get(), map_.address(plc::HoldingRegister::CellReady), 5, regs.data()) != 5)
      throw std::runtime_error(std::string("reading the cell's answer: ") + modbus_strerror(errno));
    return {regs[0] != 0, regs[1] != 0, regs[2] != 0, static_cast<plc::LineVerdict>(regs[3]),
            static_cast<plc::LineError>(regs[4])};
  }
  // Polls the answer every 20 ms until `done` holds; the time it took, or nothing at the timeout.
  std::optional<double> waitFor(const std::function<bool(const plc::CellAnswer&)>& done, std::chrono::seconds timeout) {
    const auto start = std::chrono::steady_clock::now();
    while (std::chrono::steady_clock::now() - start < timeout) {
      if (done(answer())) return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return std::nullopt;
  }

 private:
  void write(plc::HoldingRegister reg, std::uint16_t value) {
    if (modbus_write_register(context_.get(), map_.address(reg), value) != 1)
      throw std::runtime_error(std::string("writing ") + std::string(plc::describe(reg).name) + ": " +
                               modbus_strerror(errno));
  }

  std::unique_ptr<modbus_t, void (*)(modbus_t*)> context_;
  plc::RegisterMap map_;
};

std::string text(const plc::CellAnswer& a) {
  return std::string("ready ") + (a.ready ? "1" : "0") + ", busy " + (a.busy ? "1" : "0") + ", done " +
         (a.done ? "1" : "0") + ", verdict " + std::string(plc::describe(a.verdict).name) + ", error " +
         std::to_string(static_cast<int>(a.error));
}

// The number the line starts the virtual cell's sample pan by (station/src/program_library.cpp:
// simulatedProgramNames, the seventh), read from the panel's program list as a line's integrator
// would read the library.
std::uint16_t lineNumberOf(const json& programs, const std::string& name) {
  for (const json& p : programs["programs"])
    if (p["name"] == name && p["line_number"].is_number()) return p["line_number"].get<std::uint16_t>();
  return 0;
}

TEST_F(HmiTest, TheLinesPlcStartsAScanOfAProgramAndReadsItsVerdict) {
  ASSERT_NO_FATAL_FAILURE(startPanel());
  const json programs = body(client_->Get("/api/programs"));
  const std::uint16_t sample = lineNumberOf(programs, "sim-pan-circle-sample");
  ASSERT_GT(sample, 0) << programs.dump(2);

  // The panel hosts the virtual cell's PLC on a free port, and prints it.
  int plc_port = 0;
  for (int i = 0; i < 100 && plc_port == 0; ++i) {
    const std::string log = station_->log();
    const std::string marker = "handshake registers of the PLC at 127.0.0.1:";
    if (const auto at = log.find(marker); at != std::string::npos) plc_port = std::atoi(log.c_str() + at + marker.size());
    else std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_GT(plc_port, 0) << station_->log();
  LineSide line(plc_port);
  // The cell says it is ready once it watches the line and its devices answer.
  ASSERT_TRUE(line.waitFor([](const plc::CellAnswer& a) { return a.ready; }, std::chrono::seconds(60)))
      << text(line.answer()) << "\n" << station_->log();
  EXPECT_FALSE(line.answer().busy);

  // A request the cell cannot take is answered at once: an unknown program, a bad part id.
  line.request(60000, "P-1");
  ASSERT_TRUE(line.waitFor([](const plc::CellAnswer& a) { return a.done; }, std::chrono::seconds(5)));
  plc::CellAnswer a = line.answer();
  EXPECT_EQ(a.verdict, plc::LineVerdict::Error) << text(a);
  EXPECT_EQ(a.error, plc::LineError::UnknownProgram) << text(a);
  EXPECT_FALSE(a.ready);
  EXPECT_FALSE(a.busy);
  line.drop();  // done held until the request drops, then dropped
  ASSERT_TRUE(line.waitFor([](const plc::CellAnswer& x) { return !x.done && x.ready; }, std::chrono::seconds(5)))
      << text(line.answer());
  EXPECT_EQ(line.answer().error, plc::LineError::UnknownProgram) << "the answer stays until the next request";
  line.request(sample, "../etc");
  ASSERT_TRUE(line.waitFor([](const plc::CellAnswer& x) { return x.done; }, std::chrono::seconds(5)));
  EXPECT_EQ(line.answer().error, plc::LineError::BadPartId) << text(line.answer());
  line.drop();
  ASSERT_TRUE(line.waitFor([](const plc::CellAnswer& x) { return !x.done && x.ready; }, std::chrono::seconds(5)));

  // While a person's scan runs the line is refused "busy".
  const std::string token = csrf();
  auto started = post("/api/scan/start", R"({"part_id": "by-hand"})", token);
  ASSERT_TRUE(started);
  ASSERT_EQ(started->status, 202) << started->body;
  EXPECT_TRUE(line.waitFor([](const plc::CellAnswer& x) { return !x.ready; }, std::chrono::seconds(2)).has_value());
  line.request(sample, "P-2");
  ASSERT_TRUE(line.waitFor([](const plc::CellAnswer& x) { return x.done; }, std::chrono::seconds(5)));
  EXPECT_EQ(line.answer().error, plc::LineError::Busy) << text(line.answer());
  EXPECT_FALSE(body(client_->Get("/api/status"))["by_line"].get<bool>());
  line.drop();
  ASSERT_EQ(post("/api/scan/abort", "{}", token)->status, 202);
  ASSERT_TRUE(line.waitFor([](const plc::CellAnswer& x) { return !x.done && x.ready; }, std::chrono::seconds(60)))
      << text(line.answer());

  // The line's own scan, dropped while it runs: aborted, and answered so.
  line.request(sample, "P-3");
  ASSERT_TRUE(line.waitFor([](const plc::CellAnswer& x) { return x.busy; }, std::chrono::seconds(5)));
  const json running = body(client_->Get("/api/status"));
  EXPECT_TRUE(running["by_line"].get<bool>()) << running.dump();
  EXPECT_EQ(running["part_id"], "P-3");
  line.drop();
  ASSERT_TRUE(line.waitFor([](const plc::CellAnswer& x) { return !x.busy; }, std::chrono::seconds(60)));
  EXPECT_EQ(line.answer().verdict, plc::LineVerdict::Error) << text(line.answer());
  EXPECT_EQ(line.answer().error, plc::LineError::Aborted) << text(line.answer());
  ASSERT_TRUE(line.waitFor([](const plc::CellAnswer& x) { return !x.done && x.ready; }, std::chrono::seconds(10)));

  // The whole handshake: request, busy, the verdict with done, the request dropped, done dropped.
  line.request(sample, "P-0001");
  const std::optional<double> to_busy = line.waitFor([](const plc::CellAnswer& x) { return x.busy; }, std::chrono::seconds(5));
  ASSERT_TRUE(to_busy) << text(line.answer());
  EXPECT_FALSE(line.answer().ready);
  const std::optional<double> to_done =
      line.waitFor([](const plc::CellAnswer& x) { return x.done; }, std::chrono::seconds(600));
  ASSERT_TRUE(to_done) << text(line.answer()) << "\n" << station_->log();
  a = line.answer();
  EXPECT_FALSE(a.busy);
  EXPECT_TRUE(a.verdict == plc::LineVerdict::Good || a.verdict == plc::LineVerdict::Marginal ||
              a.verdict == plc::LineVerdict::Failed)
      << text(a);
  EXPECT_EQ(a.error, plc::LineError::None) << text(a);
  // The run knows who started it, and the panel shows it.
  const json runs = body(client_->Get("/api/runs"));
  std::string run_id;
  for (const json& r : runs["runs"])
    if (r["part_id"] == "P-0001") run_id = r["run_id"];
  ASSERT_FALSE(run_id.empty()) << runs.dump(2);
  const json details = body(client_->Get(("/api/runs/" + run_id).c_str()));
  EXPECT_NE(details["run"]["started_by"].get<std::string>().find("line"), std::string::npos) << details["run"].dump(2);
  EXPECT_EQ(plc::describe(a.verdict).name, details["report"]["verdict"].get<std::string>());
  line.drop();
  ASSERT_TRUE(line.waitFor([](const plc::CellAnswer& x) { return !x.done && x.ready; }, std::chrono::seconds(5)));
  const json cell = body(client_->Get("/api/cell"));
  EXPECT_TRUE(cell["line"]["connected"].get<bool>()) << cell["line"].dump();
  const json measurement = details["run"].value("measurement", json::object());
  std::printf("the line's request to cell_busy: %.3f s; cell_busy to cell_done: %.1f s (the measurement after the "
              "last sweep: %.1f s)\n",
              *to_busy, *to_done, measurement.value("seconds_after_scan", -1.0));
}

}  // namespace
}  // namespace stampscan::hmi::test
