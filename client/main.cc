// orbatlas: command-line entry point. Sub-commands live in cmd_*.cc.
#include <exception>
#include <iostream>

#include "client/commands.h"
#include "core/common/error.h"

int main(int argc, char** argv) {
  CLI::App app{"orbatlas: multisession visual(-inertial) SLAM with a persistent atlas"};
  app.require_subcommand(1);
  orbatlas::cli::register_sim_command(app);
  orbatlas::cli::register_eval_command(app);
  orbatlas::cli::register_bench_command(app);
  orbatlas::cli::register_vocab_command(app);
  orbatlas::cli::register_run_command(app);
  orbatlas::cli::register_localize_command(app);
  orbatlas::cli::register_remote_commands(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const orbatlas::Error& e) {
    std::cerr << "orbatlas: error: " << e.what() << "\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "orbatlas: unexpected error: " << e.what() << "\n";
    return 2;
  }
  return 0;
}
