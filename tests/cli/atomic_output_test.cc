// Outputs are written atomically and never over an input (SPEC §4), checked on the program as a user
// runs it: (i) a command whose output is one of its inputs refuses with exit code 2 and leaves every
// file as it was; (ii) a run interrupted by SIGINT or SIGKILL while it works leaves the results of an
// earlier run byte-for-byte intact (and, for SIGINT, no temporary file).

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <regex>
#include <string>
#include <thread>

#include "cli_test_util.h"
#include "stagefit/model/model_file.h"

namespace stagefit {
namespace {

namespace fs = std::filesystem;
using testing::ReadBytes;
using testing::RunStagefit;
using testing::Substitute;
using testing::TempDir;
using testing::WriteBytes;

// Every file under `dir` with its content.
std::map<std::string, std::string> Snapshot(const fs::path& dir) {
  std::map<std::string, std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (e.is_regular_file()) files[fs::relative(e.path(), dir).string()] = ReadBytes(e.path());
  }
  return files;
}

void Run(const std::string& arguments) {
  const auto r = RunStagefit(arguments);
  if (r.exit_code != 0) throw std::runtime_error("stagefit " + arguments + " failed:\n" + r.output);
}

// Inputs the cases need, written into the case's folder.
void Model(const fs::path& dir, const std::string& name) { WriteBytes(dir / name, std::string(model::DefaultModelToml())); }
void Measurement(const fs::path& dir, const std::string& name) {
  Run("synthesize --points 12 --out " + (dir / name).string());
}
void Record(const fs::path& dir) {
  WriteBytes(dir / "record.csv", ReadBytes(std::string(STAGEFIT_SOURCE_DIR) + "/measurements/disturbance/ground_l4c_voltage.csv"));
}
void Sensitivity(const fs::path& dir) {
  Run("disturbance sensitivity --fmin 1 --fmax 100 --points 40 --out " + (dir / "sensitivity.csv").string());
  std::ifstream in(dir / "sensitivity.csv");
  std::string psd = "frequency_hz,motion\n";
  for (std::string line; std::getline(in, line);) {
    if (!line.empty() && std::isdigit(static_cast<unsigned char>(line[0]))) psd += line.substr(0, line.find(',')) + ",1e-18\n";
  }
  WriteBytes(dir / "psd.csv", psd);
}

struct OverInput {
  std::string name;
  std::function<void(const fs::path& dir)> make;  ///< writes valid inputs: without the check the command would succeed
  std::string command;                            ///< {dir} stands for the case's folder
};

void PrintTo(const OverInput& c, std::ostream* os) { *os << c.name; }

std::vector<OverInput> OverInputCases() {
  return {
      {"ModelReportOverModel", [](const fs::path& d) { Model(d, "m.toml"); },
       "model --model {dir}/m.toml --report {dir}/m.toml"},
      {"CompareReportOverMeasurement", [](const fs::path& d) { Measurement(d, "m.mat"); },
       "compare --measurement {dir}/m.mat --report {dir}/m.mat"},
      {"FitOutOverModel",
       [](const fs::path& d) {
         Model(d, "m.toml");
         Measurement(d, "m.mat");
       },
       "fit --model {dir}/m.toml --measurement {dir}/m.mat --params hexapod.k.Dz --max-iterations 1 --out {dir}/m.toml"},
      {"FitReportOverMeasurement", [](const fs::path& d) { Measurement(d, "m.mat"); },
       "fit --measurement {dir}/m.mat --params hexapod.k.Dz --max-iterations 1 --report {dir}/m.mat"},
      {"FitOutOverRecipe",
       [](const fs::path& d) {
         Measurement(d, "m.mat");
         WriteBytes(d / "recipe.toml", "params = [\"hexapod.k.Dz\"]\nmax_iterations = 1\n");
       },
       "fit --recipe {dir}/recipe.toml --measurement {dir}/m.mat --out {dir}/recipe.toml"},
      {"ExportMatOverModel", [](const fs::path& d) { Model(d, "m.mat"); }, "export --model {dir}/m.mat --out {dir}/m.mat"},
      {"ExportCsvMatrixOverModel", [](const fs::path& d) { Model(d, "ss_K.csv"); },
       "export --model {dir}/ss_K.csv --out {dir}/ss.csv"},
      {"FrfOutOverMeasurement", [](const fs::path& d) { Measurement(d, "m.csv"); },
       "frf --measurement {dir}/m.csv --out {dir}/m.csv"},
      {"FrfOutOverMeasurementSidecar", [](const fs::path& d) { Measurement(d, "m.csv"); },
       "frf --measurement {dir}/m.csv --out {dir}/m.geometry.csv"},
      {"SynthesizeOutOverModel", [](const fs::path& d) { Model(d, "m.mat"); },
       "synthesize --points 12 --model {dir}/m.mat --out {dir}/m.mat"},
      {"SynthesizeRawOverModel", [](const fs::path& d) { Model(d, "m.mat"); },
       "synthesize --points 12 --model {dir}/m.mat --out {dir}/new.mat --raw {dir}/m.mat"},
      {"DiagnoseOutOverModel",
       [](const fs::path& d) {
         Model(d, "m.toml");
         Measurement(d, "m.mat");
       },
       "diagnose --model {dir}/m.toml --measurement {dir}/m.mat --effects payload --out {dir}/m.toml"},
      {"EstimateOutOverRaw", [](const fs::path& d) { Run("synthesize --points 12 --out " + (d / "m.mat").string() + " --raw " + (d / "raw.mat").string()); },
       "estimate {dir}/raw.mat --out {dir}/raw.mat"},
      {"DisturbancePsdOutOverRecord", Record, "disturbance psd {dir}/record.csv --kind ground-geophone --out {dir}/record.csv"},
      {"DisturbancePsdReportOverRecord", Record,
       "disturbance psd {dir}/record.csv --kind ground-geophone --out {dir}/psd.csv --report {dir}/record.csv"},
      {"DisturbanceSynthOutOverPsd", Sensitivity, "disturbance synth --psd {dir}/psd.csv --duration 1 --out {dir}/psd.csv"},
      {"DisturbanceForceOutOverSensitivity", Sensitivity,
       "disturbance force --psd {dir}/psd.csv --sensitivity {dir}/sensitivity.csv --out {dir}/sensitivity.csv"},
      {"DisturbanceSensitivityOutOverItsFrequencies", Sensitivity,
       "disturbance sensitivity --at {dir}/psd.csv --out {dir}/psd.csv"},
      {"SimulateOutputOverTheMeasuredSeries",
       [](const fs::path& d) { Run("simulate tomography --duration 0.5 --rate 1000 --out-dir " + d.string()); },
       "simulate tomography --duration 0.5 --rate 1000 --out-dir {dir} --compare {dir}/tomography.csv"},
  };
}

class OverInputTest : public ::testing::TestWithParam<OverInput> {};

TEST_P(OverInputTest, RefusesWithExitTwoAndChangesNothing) {
  const OverInput& c = GetParam();
  const fs::path dir = TempDir("over_input_" + c.name);
  ASSERT_NO_THROW(c.make(dir));
  const auto before = Snapshot(dir);
  const auto r = RunStagefit(Substitute(c.command, dir));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("is also an input"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("refusing to write over an input"), std::string::npos) << r.output;
  EXPECT_TRUE(Snapshot(dir) == before) << "files changed, appeared or disappeared";
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(Commands, OverInputTest, ::testing::ValuesIn(OverInputCases()),
                         [](const ::testing::TestParamInfo<OverInput>& info) { return info.param.name; });

// ---- interrupted runs ----

// Starts stagefit with `arguments` (stdout and stderr to `log`) and returns its process id.
pid_t Start(const std::string& arguments, const fs::path& log) {
  const std::string command = "exec " + std::string(STAGEFIT_BINARY) + " " + arguments + " > '" + log.string() + "' 2>&1";
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::execl("/bin/sh", "sh", "-c", command.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  return pid;
}

// Writes results with a short fit, then starts the same command as a long fit (thousands of starts)
// over the same outputs, lets it work for a moment and sends `signal_number`. Returns the wait status
// and the process id of the interrupted run; `before` and `after` are the folder's files.
struct Interrupted {
  int status = 0;
  pid_t pid = 0;
  std::map<std::string, std::string> before, after;
};

Interrupted InterruptLongFit(const fs::path& dir, int signal_number) {
  Interrupted result;
  Measurement(dir, "m.mat");
  const std::string outputs = " --out " + (dir / "tuned.toml").string() + " --report " + (dir / "fit.json").string();
  const auto first = RunStagefit("fit --measurement " + (dir / "m.mat").string() +
                                 " --params hexapod.k.Dz --max-iterations 1" + outputs);
  if (first.exit_code != 0 && first.exit_code != 3) throw std::runtime_error(first.output);
  result.before = Snapshot(dir);
  const fs::path log = fs::temp_directory_path() / ("stagefit_interrupted_" + std::to_string(signal_number) + ".log");
  result.pid = Start("fit --measurement " + (dir / "m.mat").string() + " --starts 100000" + outputs, log);
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  int status = 0;
  if (::waitpid(result.pid, &status, WNOHANG) != 0) {
    throw std::runtime_error("the long fit ended before it was interrupted:\n" + ReadBytes(log));
  }
  ::kill(result.pid, signal_number);
  ::waitpid(result.pid, &result.status, 0);
  fs::remove(log);
  result.after = Snapshot(dir);
  return result;
}

TEST(InterruptedRun, SigintLeavesEarlierResultsIntactAndNoTemporaryFile) {
  const fs::path dir = TempDir("interrupted_sigint");
  Interrupted r;
  ASSERT_NO_THROW(r = InterruptLongFit(dir, SIGINT));
  ASSERT_TRUE(r.before.count("tuned.toml") && r.before.count("fit.json"));
  EXPECT_TRUE(WIFSIGNALED(r.status) && WTERMSIG(r.status) == SIGINT) << "status " << r.status;
  EXPECT_TRUE(r.after == r.before) << "an interrupted run changed or left files";
  fs::remove_all(dir);
}

TEST(InterruptedRun, SigkillLeavesEarlierResultsIntact) {
  const fs::path dir = TempDir("interrupted_sigkill");
  Interrupted r;
  ASSERT_NO_THROW(r = InterruptLongFit(dir, SIGKILL));
  EXPECT_TRUE(WIFSIGNALED(r.status) && WTERMSIG(r.status) == SIGKILL) << "status " << r.status;
  for (const auto& [name, content] : r.before) {
    ASSERT_TRUE(r.after.count(name)) << name << " disappeared";
    EXPECT_TRUE(r.after.at(name) == content) << name << " changed";
  }
  // SIGKILL cannot be caught: a write in progress may leave its temporary file, recognisable by name.
  const std::regex temporary("(tuned\\.toml|fit\\.json)\\.tmp-" + std::to_string(r.pid) + "-[0-9]+");
  for (const auto& [name, content] : r.after) {
    if (!r.before.count(name)) {
      EXPECT_TRUE(std::regex_match(name, temporary)) << "unexpected file " << name;
    }
  }
  fs::remove_all(dir);
}

TEST(InterruptedRun, FailingRunLeavesEarlierResultsIntact) {
  const fs::path dir = TempDir("failing_run");
  ASSERT_EQ(RunStagefit("model --report " + (dir / "r.json").string()).exit_code, 0);
  WriteBytes(dir / "bad.toml", "[[body]]\nname = \"b\"\nmass = -1\n");
  const auto before = Snapshot(dir);
  const auto r = RunStagefit("model --model " + (dir / "bad.toml").string() + " --report " + (dir / "r.json").string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_TRUE(Snapshot(dir) == before);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace stagefit
