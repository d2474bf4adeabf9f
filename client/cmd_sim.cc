#include "client/commands.h"
namespace orbatlas::cli {
void register_sim_command(CLI::App&) {}  // placeholder: being written
}  // namespace orbatlas::cli
