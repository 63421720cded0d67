// `station hmi`: the operator's panel in the browser. A thin caller of station/hmi (the server, the
// API and the page): it reads the options, hosts the virtual cell when no --cell is given (as
// `station scan` does), prepares the scan and the verification the panel may start, and serves.
#include "stampscan/hmi/auth.hpp"
#include "stampscan/hmi/hmi_server.hpp"
#include "stampscan/hmi/panel_log.hpp"
#include "stampscan/hmi/tls_front.hpp"
#include "stampscan/station/commands.hpp"
#include "stampscan/jobs/calibration_results.hpp"
#include "stampscan/jobs/calibrate_job.hpp"
#include "stampscan/jobs/verify_job.hpp"
#include "cell_choice.hpp"
#include "panel_programs.hpp"
#include "program_library.hpp"
#include "stop_signals.hpp"
#include "virtual_cell/virtual_cell_host.hpp"

#include <atomic>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <thread>

namespace stampscan::station {

namespace {

namespace fs = std::filesystem;

// The virtual cell's own part on the panel, when no program puts another there: the sample pan.
constexpr const char* kPanelPart = "pan";
constexpr const char* kPanelGrid = "circle";

struct HmiCommandOptions {
  CellChoice cell;
  std::string listen = "127.0.0.1:8080", users, runs = "stampscan-runs", calibration_dir, web, ready_file;
  bool hash_password = false, front_config = false, allow_plain_http = false;
  std::uint64_t seed = 1;
};

// On the built-in virtual cell: SIGUSR1 opens the cell's door, SIGUSR2 closes it, so that a fault
// can be rehearsed (and tested) on the panel. The handler only records which; the watcher acts.
std::atomic<int> g_virtual_door{0};
extern "C" void onVirtualDoor(int sig) { g_virtual_door = sig; }

int hashPasswordFromStdin() {
  std::string password;
  std::getline(std::cin, password);
  if (password.empty()) {
    std::fprintf(stderr, "station hmi --hash-password: give the password on standard input\n");
    return 1;
  }
  std::printf("%s\n", hmi::hashPassword(password).c_str());
  return 0;
}


hmi::HmiOptions panelOptions(const HmiCommandOptions& opt, bool listen_given, const acquisition::CellConfig& config) {
  const acquisition::CellConfig::Panel& panel = config.panel;
  hmi::HmiOptions options;
  options.listen = listen_given ? opt.listen : panel.listen;
  options.users_file = !opt.users.empty() ? opt.users : panel.users_file;
  options.web_dir = opt.web;
  options.server_names = panel.server_names;
  options.behind_tls_front = panel.behindTlsFront();
  options.allow_plain_http = opt.allow_plain_http;
  return options;
}

// --front-config: the site file of the panel's TLS front on standard output.
int printFrontConfig(const acquisition::CellConfig& config, const hmi::HmiOptions& options) {
  const acquisition::CellConfig::Panel& panel = config.panel;
  if (!panel.behindTlsFront())
    throw std::runtime_error(config.source + ": [hmi] has no tls_certificate and tls_key: the panel has no TLS "
                                             "front to configure");
  hmi::TlsFront front;
  front.cell_name = config.name;
  front.upstream = options.listen;
  front.server_names = panel.server_names;
  front.certificate = fs::absolute(panel.tls_certificate).string();
  front.key = fs::absolute(panel.tls_key).string();
  front.https_port = panel.https_port;
  front.http_port = panel.http_port;
  std::fputs(hmi::nginxSite(front).c_str(), stdout);
  return 0;
}

// The scan the panel starts without a program: on the virtual cell, its sample pan's region (the
// program sim-pan-circle-sample), as `station scan`; a real cell scans only programs.
jobs::ScanJobOptions panelScan(const acquisition::CellConfig& config, bool virtual_cell, const HmiCommandOptions& opt,
                         const fs::path& calibration_dir) {
  jobs::ScanJobOptions scan;
  if (virtual_cell) {
    const acquisition::PartProgram sample =
        programFromLibrary(simulatedProgramName(kPanelPart, kPanelGrid, true), config, true, opt.runs);
    scan.plan = programPlan(sample, config, acquisition::calibrationScenes(config.calibration, 0.5, opt.seed), true);
    scan.plan.name = sample.name + ", laser and stereo, with calibration scenes";
    scan.part_program = jobs::PartProgramRef{sample.name, sample.folder.string()};
  }
  scan.run.limits = config.limits;
  scan.run.session = acquisition::describeSession(config.geometry, scan.plan);
  scan.runs_dir = opt.runs;
  scan.results_database = config.results_database;
  scan.calibration_dir = calibration_dir;
  scan.calibration_policy = config.calibration;
  return scan;
}

// The verification of the digitizer: every sphere sweep of the calibration and the ball bar, as
// `station verify` (the stereo pair's check on the plate stays with the command, whose cameras take
// the calibration's resolution).
jobs::VerifyJobOptions panelVerify(const acquisition::CellConfig& config, const fs::path& calibration_dir, std::uint64_t seed) {
  jobs::VerifyJobOptions verify = jobs::cellVerification(config, calibration_dir);
  verify.plan = jobs::cellVerificationPlan(config, seed);
  verify.run.session = acquisition::describeSession(config.geometry, verify.plan);
  verify.run.session.part_id = "reference sphere";
  return verify;
}

// The calibration: the cell's calibration scenes (every sphere sweep and plate view) at the hosted
// cameras' resolution, as `station calibrate`.
jobs::CalibrateJobOptions panelCalibrate(const acquisition::CellConfig& config, const fs::path& calibration_dir,
                                         std::uint64_t seed) {
  jobs::CalibrateJobOptions calibrate = jobs::cellCalibration(config, calibration_dir);
  calibrate.plan = jobs::cellCalibrationPlan(config, seed);
  calibrate.run.session = acquisition::describeSession(config.geometry, calibrate.plan);
  calibrate.run.session.part_id = "calibration";
  return calibrate;
}

void printServing(const acquisition::CellConfig& config, const hmi::HmiServer& server, const hmi::HmiOptions& options,
                  bool hosted) {
  std::printf("station hmi: %s%s on %s%s\n", config.name.c_str(), hosted ? " (hosted in this process)" : "",
              server.url().c_str(),
              options.behind_tls_front ? " (login required; served through its TLS front)"
              : server.loginRequired() ? " (login required)"
                                       : "");
  if (server.loginRequired() && !options.behind_tls_front)
    std::fprintf(stderr, "station hmi: warning: served off loopback without TLS (--allow-plain-http): passwords and "
                         "session cookies travel in clear text\n");
  if (config.plc_line_start)
    std::printf("station hmi: the line's PLC may start scans: the handshake registers of the PLC at %s:%d (unit %d) "
                "are watched\n",
                config.plc.host.c_str(), config.plc.port, config.plc_unit_id);
  std::fflush(stdout);
}

// Serves until SIGINT or SIGTERM (stop_signals.hpp, as the commands on the cell). Beside the server
// a watcher thread logs the cell's health (first once the devices have had time to connect, then
// every minute) and, on the virtual cell, opens and closes its door on SIGUSR1 and SIGUSR2.
void serveUntilStopped(hmi::HmiServer& server, VirtualCellHost* hosted) {
  const StopSignalGuard stop([&server](const std::string&) { server.stop(); });
  std::atomic<bool> done{false};
  if (hosted) {
    std::signal(SIGUSR1, onVirtualDoor);
    std::signal(SIGUSR2, onVirtualDoor);
  }
  std::thread watcher([&] {
    hmi::HealthLog health_log;
    auto next_health = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (!done) {
      if (std::chrono::steady_clock::now() >= next_health) {
        try {
          health_log.update(server.health());
        } catch (const std::exception& e) {
          hmi::logLine(hmi::kLogWarning, std::string("warning: the cell's health could not be checked: ") + e.what());
        }
        next_health = std::chrono::steady_clock::now() + std::chrono::seconds(60);
      }
      if (const int door = g_virtual_door.exchange(0); door != 0 && hosted) {
        if (door == SIGUSR1) hosted->openDoor();
        else hosted->closeDoor();
        std::printf("station hmi: the virtual cell's door is %s\n", door == SIGUSR1 ? "open" : "closed");
        std::fflush(stdout);
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  });
  server.run();
  done = true;
  watcher.join();
}

int runHmi(const HmiCommandOptions& opt, bool listen_given) {
  if (opt.hash_password) return hashPasswordFromStdin();
  CommandCell command_cell = opt.cell.open();
  const acquisition::CellConfig& config = command_cell.config;
  const bool virtual_cell = command_cell.virtual_cell;
  const hmi::HmiOptions options = panelOptions(opt, listen_given, config);
  if (opt.front_config) return printFrontConfig(config, options);
  // Bad options are refused before the virtual cell is hosted: it takes the GigE Vision port.
  hmi::HmiServer::checkOptions(options);

  // The panel's sessions are quick ones: the virtual cameras at a quarter of their resolution.
  VirtualWorld world;
  world.quick = true;
  world.part = kPanelPart;
  world.grid = kPanelGrid;
  world.options.seed = opt.seed;
  VirtualCellHost* hosted = command_cell.simulate(world);
  hmi::CellSetup setup;
  setup.calibration_dir = jobs::calibrationFolder(opt.calibration_dir, config.calibration, opt.runs);
  setup.scan = panelScan(config, virtual_cell, opt, setup.calibration_dir);
  setup.verify = panelVerify(config, setup.calibration_dir, opt.seed);
  setup.calibrate = panelCalibrate(config, setup.calibration_dir, opt.seed);

  // The embedded virtual cell first: hosting may re-execute this program (umockdev).
  command_cell.serveToMeasure(true);
  if (hosted) setup.scan.truth = hosted->truthOfPart();
  setup.programs = panelPrograms(config, virtual_cell, opt.runs, opt.seed, hosted);
  setup.line_start = config.plc_line_start;
  acquisition::Cell cell(config);
  setup.cell = &cell;
  hmi::HmiServer server(std::move(setup), options);
  server.bind();
  printServing(config, server, options, hosted != nullptr);
  std::printf("station hmi: priority %s\n", command_cell.priorityNote().c_str());
  std::fflush(stdout);
  if (!opt.ready_file.empty()) std::ofstream(opt.ready_file) << server.url() << '\n';
  serveUntilStopped(server, hosted);
  std::printf("station hmi: stopped\n");
  return 0;
}

}  // namespace

CommandRunner addHmiCommand(CLI::App& app) {
  auto opt = std::make_shared<HmiCommandOptions>();
  CLI::App* cmd = app.add_subcommand("hmi", "The operator's panel in the browser: cell view, scan, results, history, "
                                            "calibration (default: the built-in virtual cell on http://127.0.0.1:8080/)");
  opt->cell.addTo(cmd);
  CLI::Option* listen = cmd->add_option("--listen", opt->listen, "HOST:PORT to serve on (port 0: any free one); any "
                                                                "address but loopback requires a login; default: [hmi] "
                                                                "listen in the cell file, or 127.0.0.1:8080");
  cmd->add_option("--users", opt->users, "Users file (TOML: [[user]] name, role, password_hash); default: [hmi] users "
                                         "in the cell file");
  cmd->add_option("-o,--runs", opt->runs, "Folder of run folders and the results database");
  cmd->add_option("--calibration-dir", opt->calibration_dir, "The cell's calibration folder (default: RUNS/calibration)");
  cmd->add_option("--web", opt->web, "Serve the page from this folder instead of the built-in copy (development)");
  cmd->add_option("--ready-file", opt->ready_file, "Write the panel's URL into this file once it serves (for scripts)");
  cmd->add_option("--seed", opt->seed, "The virtual cell's seed");
  cmd->footer("On the built-in virtual cell, SIGUSR1 opens the cell door and SIGUSR2 closes it (to rehearse a fault).");
  cmd->add_flag("--hash-password", opt->hash_password,
                "Read a password on standard input, print its hash for the users file, and exit");
  cmd->add_flag("--allow-plain-http", opt->allow_plain_http,
                "Serve off loopback without the TLS front, passwords in clear text (a closed test bench only)");
  cmd->add_flag("--front-config", opt->front_config,
                "Print the site file of the panel's TLS front (Debian's nginx) for the cell file's [hmi] section, "
                "and exit");
  return [opt, listen]() { return runHmi(*opt, listen->count() > 0); };
}

}  // namespace stampscan::station
