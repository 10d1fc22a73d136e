#include <iostream>

#include "command.h"
#include "stagefit/common/atomic_file.h"
#include "stagefit/common/error.h"
#include "stagefit/common/memory.h"
#include "stagefit/common/parallel.h"
#include "stagefit/fit/least_squares.h"

namespace stagefit::cli {

int& ExitCode() {
  static int code = kExitOk;
  return code;
}

}  // namespace stagefit::cli

int main(int argc, char** argv) {
  using namespace stagefit::cli;
  // An interrupted run (Ctrl-C) leaves the earlier outputs intact and no temporary file behind.
  stagefit::RemoveTemporaryFilesOnSignal();
  stagefit::KeepFreedMemory();  // fits allocate and free large arrays per evaluation
  stagefit::fit::SilenceSolverLog();  // the fits handle a failed evaluation; Ceres would log each
  CLI::App app{"stagefit: models of precision positioning stages, tuned against vibration measurements"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "stagefit 0.1.0");
  app.add_option_function<int>(
         "--threads", [](int threads) { stagefit::SetMaxThreads(threads); },
         "threads for the FRF evaluations (default: STAGEFIT_THREADS, else every core); results do not "
         "depend on it")
      ->check(CLI::Range(1, 1024));

  // The table of subcommands.
  RegisterModelCommand(app);
  RegisterPoseCommand(app);
  RegisterExportCommand(app);
  RegisterFrfCommand(app);
  RegisterSynthesizeCommand(app);
  RegisterDiagnoseCommand(app);
  RegisterDisturbanceCommand(app);
  RegisterEstimateCommand(app);
  RegisterCompareCommand(app);
  RegisterFitCommand(app);
  RegisterLoopCommand(app);
  RegisterSimulateCommand(app);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    int code = app.exit(e);
    return code == 0 ? kExitOk : kExitUsage;
  } catch (const stagefit::UsageError& e) {
    std::cerr << "stagefit: usage error: " << e.what() << "\n";
    return kExitUsage;
  } catch (const stagefit::InputError& e) {
    std::cerr << "stagefit: error: " << e.what() << "\n";
    return kExitBadInput;
  } catch (const stagefit::NumericalError& e) {
    std::cerr << "stagefit: numerical failure: " << e.what() << "\n";
    return kExitNumerics;
  } catch (const std::bad_alloc&) {
    std::cerr << "stagefit: error: out of memory (an input declares sizes too large to hold)\n";
    return kExitBadInput;
  } catch (const std::exception& e) {
    std::cerr << "stagefit: internal error: " << e.what() << "\n";
    return 4;
  }
  return ExitCode();
}
