// station: the StampScan command-line program.
#include "stampscan/station/commands.hpp"

#include <cstdio>
#include <exception>

int main(int argc, char** argv) {
  CLI::App app{"StampScan: sheet-metal forming inspection: scan, fit, strain map"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "station 0.1.0");
  stampscan::station::CommandRunner fit = stampscan::station::addFitCommand(app);
  stampscan::station::CommandRunner sample = stampscan::station::addSampleCommand(app);
  stampscan::station::CommandRunner demo = stampscan::station::addDemoCommand(app);
  stampscan::station::CommandRunner sim = stampscan::station::addSimCommand(app);
  stampscan::station::CommandRunner process = stampscan::station::addProcessCommand(app);
  stampscan::station::CommandRunner devices = stampscan::station::addDevicesCommand(app);
  stampscan::station::CommandRunner trace = stampscan::station::addTraceCommand(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  try {
    if (app.got_subcommand("fit")) return fit();
    if (app.got_subcommand("sample")) return sample();
    if (app.got_subcommand("demo")) return demo();
    if (app.got_subcommand("sim")) return sim();
    if (app.got_subcommand("process")) return process();
    if (app.got_subcommand("devices")) return devices();
    if (app.got_subcommand("trace")) return trace();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "station: error: %s\n", e.what());
    return 1;
  }
  return 2;
}
