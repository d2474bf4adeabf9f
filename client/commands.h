#pragma once
// Each sub-command registers itself on the CLI11 app; its callback does the work
// and throws orbatlas::Error on failure (main prints it and exits with 1).
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "core/pipeline/dataset_runner.h"

namespace orbatlas::cli {

void register_sim_command(CLI::App& app);
void register_eval_command(CLI::App& app);
void register_bench_command(CLI::App& app);
void register_vocab_command(CLI::App& app);
void register_run_command(CLI::App& app);
void register_localize_command(CLI::App& app);
// stream, sessions, maps (cmd_remote.cc): clients of a running map server.
void register_remote_commands(CLI::App& app);

// The figures of `orbatlas run` / `orbatlas localize` (cmd_run.cc).
void print_run_summary(const DatasetRunReport& report);
// Logs the options a command runs with (given, or their defaults), one
// `name=value` per line, as `orbatlas-server` does at start.
void log_effective_options(const CLI::App& command);
// Writes the figures as indented JSON (throws Error when the file cannot be written).
void write_stats_file(const std::string& path, const nlohmann::json& stats);

}  // namespace orbatlas::cli
