#include <unistd.h>

#include "command.h"

namespace stagefit::cli {

void AddCommonOptions(CLI::App& command, CommonOptions& options) {
  command.add_option("--model", options.model_path,
                     "model file (TOML); default: the embedded ID31 micro-station");
  command.add_option("--report", options.report_path, "write a JSON report to this file");
}

void AddWithOption(CLI::App& command, CommonOptions& options) {
  command.add_option("--with", options.with_effects,
                     "add a catalogued effect before the work: EFFECT@LOCATION[:param=value,...] "
                     "(repeatable), e.g. payload@hexapod:mass=5 kg,z=100 mm; catalogue: payload, extra-body, "
                     "servo-stiffness, joint-offset, coupled-stiffness, structural-damping, sensor-geometry, "
                     "delay, gyroscopic (README, docs/effects.md)");
}

bool StderrIsTerminal() { return ::isatty(STDERR_FILENO) != 0; }

}  // namespace stagefit::cli
