#pragma once
// The command line is thin: each subcommand file adds one CLI11 subcommand whose callback parses its
// options into library options, calls one library function, prints a brief report and sets the exit
// code. Exit codes (SPEC §4): 0 ok, 1 usage, 2 bad input, 3 numerics failed.

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace stagefit::cli {

inline constexpr int kExitOk = 0;
inline constexpr int kExitUsage = 1;
inline constexpr int kExitBadInput = 2;
inline constexpr int kExitNumerics = 3;

/// Options shared by most subcommands.
struct CommonOptions {
  std::string model_path;                  ///< --model FILE; empty = the embedded default
  std::string report_path;                 ///< --report FILE (JSON)
  std::vector<std::string> with_effects;   ///< --with EFFECT@LOCATION (repeatable)
};

/// Adds --model and --report to `command`.
void AddCommonOptions(CLI::App& command, CommonOptions& options);
/// Adds --with (repeatable) to `command`.
void AddWithOption(CLI::App& command, CommonOptions& options);

/// The exit code the subcommand callback decided on (callbacks cannot return values in CLI11).
int& ExitCode();

/// True when stderr is a terminal (progress is shown only then).
bool StderrIsTerminal();

// One Register function per subcommand file (cmd_<name>.cc); main.cc calls them in order.
void RegisterModelCommand(CLI::App& app);
void RegisterPoseCommand(CLI::App& app);
void RegisterExportCommand(CLI::App& app);
void RegisterFrfCommand(CLI::App& app);
void RegisterSynthesizeCommand(CLI::App& app);
void RegisterDiagnoseCommand(CLI::App& app);
void RegisterDisturbanceCommand(CLI::App& app);
void RegisterEstimateCommand(CLI::App& app);
void RegisterCompareCommand(CLI::App& app);
void RegisterLoopCommand(CLI::App& app);
void RegisterFitCommand(CLI::App& app);
void RegisterSimulateCommand(CLI::App& app);

}  // namespace stagefit::cli
