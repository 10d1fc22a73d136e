// A table of malformed inputs for every reader, run through the program as a user would: each must
// end with exit code 2, a message that names the file and the problem, and no output file (nor a
// temporary one) left behind. Each reader also has a control case: the same command on the
// unmodified input succeeds, so that every bad case fails because of its one defect.

#include <gtest/gtest.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli_test_util.h"
#include "stagefit/measurement/mat_file.h"
#include "stagefit/measurement/measurement_file.h"
#include "stagefit/measurement/uff58.h"
#include "stagefit/model/model_file.h"

namespace stagefit {
namespace {

namespace fs = std::filesystem;
using measurement::MatVariable;
using testing::ReadBytes;
using testing::RunStagefit;
using testing::Substitute;
using testing::TempDir;
using testing::WriteBytes;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

// ---- files as bytes and text ----

// `text` with the first `from` replaced by `to`; a missing `from` is a broken test, not a pass.
std::string Edit(std::string text, const std::string& from, const std::string& to) {
  const std::size_t at = text.find(from);
  if (at == std::string::npos) throw std::logic_error("test input has no '" + from + "'");
  return text.replace(at, from.size(), to);
}

// Everything before the first `marker` plus the marker itself: a file cut short at a known place.
std::string CutAfter(const std::string& text, const std::string& marker) {
  const std::size_t at = text.find(marker);
  if (at == std::string::npos) throw std::logic_error("test input has no '" + marker + "'");
  return text.substr(0, at + marker.size());
}

// The `n`-th (0-based) line of `text` that starts with `prefix`, replaced by `line`.
std::string ReplaceLine(const std::string& text, const std::string& prefix, int n, const std::string& line) {
  std::size_t at = 0;
  for (int seen = 0;; ++at) {
    at = text.find(prefix, at);
    if (at == std::string::npos) throw std::logic_error("test input has no line '" + prefix + "'");
    if (at != 0 && text[at - 1] != '\n') continue;
    if (seen++ == n) break;
  }
  const std::size_t end = text.find('\n', at);
  return text.substr(0, at) + line + (end == std::string::npos ? "" : text.substr(end));
}

// ---- MATLAB v5 files edited element by element ----

template <typename Derived>
MatVariable Var(std::string name, const Eigen::MatrixBase<Derived>& value) {
  return {std::move(name), Eigen::Matrix<typename Derived::Scalar, Eigen::Dynamic, Eigen::Dynamic>(value)};
}
MatVariable Var(std::string name, std::string value) { return {std::move(name), std::move(value)}; }
MatVariable Var(std::string name, std::vector<std::string> value) { return {std::move(name), std::move(value)}; }

std::uint32_t U32(const std::string& b, std::size_t at) {
  std::uint32_t v;
  std::memcpy(&v, b.data() + at, 4);
  return v;
}

// An uncompressed little-endian MAT v5 file (as the project's writer makes it) as a list of its
// top-level variables, so that a test can drop, replace or corrupt one variable.
class MatV5 {
 public:
  static MatV5 Read(const fs::path& path) {
    MatV5 m;
    const std::string b = ReadBytes(path);
    m.header_ = b.substr(0, 128);
    std::size_t at = 128;
    while (at + 8 <= b.size()) {
      if (U32(b, at) != 14) throw std::logic_error(path.string() + ": not an uncompressed miMATRIX element");
      const std::size_t end = at + 8 + ((U32(b, at + 4) + 7) / 8) * 8;
      Element e{"", b.substr(at, end - at)};
      const Sub name = Subelements(e.bytes).at(2);
      e.name = e.bytes.substr(name.data, name.size);
      m.elements_.push_back(e);
      at = end;
    }
    return m;
  }

  void Write(const fs::path& path) const {
    std::string b = header_;
    for (const Element& e : elements_) b += e.bytes;
    WriteBytes(path, b);
  }

  MatV5& Remove(const std::string& name) {
    elements_.erase(elements_.begin() + Index(name));
    return *this;
  }

  // Removes `v.name` if present and appends `v` as written by measurement::WriteMatFile.
  MatV5& Put(const MatVariable& v) {
    for (std::size_t i = 0; i < elements_.size(); ++i) {
      if (elements_[i].name == v.name) elements_.erase(elements_.begin() + i);
    }
    // Per process: CTest runs the cases in parallel, and two of them writing the same variable to one
    // file read each other's half-written or removed scratch.
    const fs::path scratch = fs::temp_directory_path() /
                             ("stagefit_bad_input_var_" + std::to_string(::getpid()) + "_" + v.name + ".mat");
    measurement::WriteMatFile(scratch, {v});
    MatV5 one = Read(scratch);
    fs::remove(scratch);
    elements_.push_back(one.elements_.at(0));
    return *this;
  }

  // Dimension `k` of the variable's header, without touching its data (a corrupt size field).
  MatV5& SetDim(const std::string& name, int k, std::int32_t value) {
    Element& e = elements_[Index(name)];
    const Sub dims = Subelements(e.bytes).at(1);
    if (4 * static_cast<std::size_t>(k) >= dims.size) throw std::logic_error(name + ": no such dimension");
    std::memcpy(e.bytes.data() + dims.data + 4 * k, &value, 4);
    return *this;
  }

  // Element `index` (column-major) of the real (part 0) or imaginary (part 1) double data.
  MatV5& SetDouble(const std::string& name, std::size_t index, double value, int part = 0) {
    Element& e = elements_[Index(name)];
    const Sub data = Subelements(e.bytes).at(3 + part);
    if (U32(e.bytes, data.data - 8) != 9 || 8 * index >= data.size) {
      throw std::logic_error(name + ": not double data of that size");
    }
    std::memcpy(e.bytes.data() + data.data + 8 * index, &value, 8);
    return *this;
  }

 private:
  struct Element {
    std::string name, bytes;
  };
  struct Sub {
    std::size_t data = 0, size = 0;
  };

  // Flags, dims, name, then the data parts (or cells) of one miMATRIX element.
  static std::vector<Sub> Subelements(const std::string& e) {
    std::vector<Sub> subs;
    std::size_t at = 8;
    while (at + 8 <= e.size()) {
      const std::uint32_t first = U32(e, at);
      if (first >> 16) {  // small data element: size in the upper half, data in the tag's 2nd word
        subs.push_back({at + 4, first >> 16});
        at += 8;
      } else {
        subs.push_back({at + 8, U32(e, at + 4)});
        at += 8 + ((subs.back().size + 7) / 8) * 8;
      }
    }
    return subs;
  }

  std::size_t Index(const std::string& name) const {
    for (std::size_t i = 0; i < elements_.size(); ++i) {
      if (elements_[i].name == name) return i;
    }
    throw std::logic_error("no variable '" + name + "' in the test file");
  }

  std::string header_;
  std::vector<Element> elements_;
};

// ---- base inputs, valid, written into a case's folder ----

// A 12 x 10 hammer measurement of the top plate with 12 frequencies, written by `synthesize` (v5,
// uncompressed; or .csv with its sidecar).
fs::path Synthesized(const fs::path& dir, const std::string& name) {
  const fs::path path = dir / name;
  const auto r = RunStagefit("synthesize --points 12 --out " + path.string());
  if (r.exit_code != 0) throw std::runtime_error("synthesize failed: " + r.output);
  return path;
}

// The first two outputs and the first input of the synthesized measurement as ASCII UFF 58.
std::string SmallUffText(const fs::path& dir) {
  measurement::FrfData data = measurement::ReadMeasurement(Synthesized(dir, "base_for_uff.mat"));
  data.outputs.resize(2);
  data.inputs.resize(1);
  for (auto& h : data.frf) h = h.topLeftCorner(2, 1).eval();
  for (auto& c : data.coherence) c = c.topLeftCorner(2, 1).eval();
  return measurement::FormatUff58(measurement::ConvertFrfDataToUff(data), measurement::UffEncoding::kAscii);
}

// Raw hammer data, one input and one hit (so that every variable is a matrix): a half-sine impact of
// 100 N and two decaying sines (40 and 90 Hz) sampled at 1024 Hz for 0.5 s.
std::vector<MatVariable> RawVariables() {
  constexpr int kSamples = 512;
  constexpr double kRate = 1024.0;
  Eigen::MatrixXd force = Eigen::MatrixXd::Zero(kSamples, 1);
  Eigen::MatrixXd response = Eigen::MatrixXd::Zero(kSamples, 2);
  for (int i = 10; i < 15; ++i) force(i, 0) = 100.0 * std::sin(M_PI * (i - 9) / 6.0);
  for (int i = 12; i < kSamples; ++i) {
    const double t = (i - 12) / kRate;
    response(i, 0) = std::exp(-t / 0.08) * std::sin(2 * M_PI * 40.0 * t);
    response(i, 1) = 0.5 * std::exp(-t / 0.05) * std::sin(2 * M_PI * 90.0 * t);
  }
  return {Var("sample_rate_hz", Eigen::MatrixXd::Constant(1, 1, kRate)),
          Var("force", force),
          Var("response", response),
          Var("response_quantity", std::string("acceleration")),
          Var("output_names", std::vector<std::string>{"a1", "a2"}),
          Var("input_names", std::vector<std::string>{"h1"})};
}

fs::path WriteRaw(const fs::path& path, const std::vector<MatVariable>& variables) {
  measurement::WriteMatFile(path, variables);
  return path;
}

// The raw base file with variable `v` replaced (or added).
fs::path WriteRawWith(const fs::path& path, const MatVariable& v) {
  auto variables = RawVariables();
  bool replaced = false;
  for (auto& x : variables) {
    if (x.name == v.name) {
      x = v;
      replaced = true;
    }
  }
  if (!replaced) variables.push_back(v);
  return WriteRaw(path, variables);
}

Eigen::MatrixXd RawMatrix(const std::string& name) {
  for (const auto& v : RawVariables()) {
    if (v.name == name) return std::get<Eigen::MatrixXd>(v.value);
  }
  throw std::logic_error("no raw variable " + name);
}

// An evenly sampled record: time_s and one voltage column, 256 rows at 100 Hz.
std::string RecordText() {
  std::string text = "# geophone record\n# unit time_s s\n# unit v V\ntime_s,v\n";
  for (int i = 0; i < 256; ++i) {
    text += std::to_string(i * 0.01) + "," + std::to_string(1e-3 * std::sin(0.3 * i) + 1e-4 * ((i * 7919) % 13)) + "\n";
  }
  return text;
}

const char kRecipe[] =
    "space = \"compliance\"\nband = [\"10 Hz\", \"400 Hz\"]\nparams = [\"hexapod.k.Dz\"]\nsolver = \"ceres\"\n"
    "max_iterations = 2\nstarts = 1\nstart_factor = 1.6\nseed = 1\n\n[[bounds]]\npattern = \"hexapod.k.*\"\n"
    "factor = 10\n";

// ---- the table ----

struct BadInput {
  std::string reader;   ///< which reader the case exercises
  std::string name;     ///< what is wrong, as a test name
  std::function<void(const fs::path& dir)> make;  ///< writes the input file(s) into the case's folder
  std::string command;  ///< arguments; {dir} stands for the case's folder
  std::vector<std::string> expected;  ///< the message must contain each (file, field, value, expectation)
};

void PrintTo(const BadInput& c, std::ostream* os) { *os << c.reader << " " << c.name; }

// Commands per reader, each with an output that must not appear when the input is bad.
const char kModelCommand[] = "model --model {dir}/bad.toml --report {dir}/out.json";
const char kMatCommand[] = "compare --measurement {dir}/bad.mat --report {dir}/out.json --out-dir {dir}/tables";
const char kCsvCommand[] = "compare --measurement {dir}/bad.csv --report {dir}/out.json";
const char kUffCommand[] = "frf --measurement {dir}/bad.uff --out {dir}/out.csv";
const char kRawCommand[] = "estimate {dir}/bad.mat --out {dir}/out.mat --report {dir}/out.json";
const char kRecordCommand[] = "disturbance psd {dir}/bad.csv --kind ground-geophone --out {dir}/out.csv --report {dir}/out.json";
const char kRecipeCommand[] = "fit --recipe {dir}/bad.toml --measurement {dir}/base.mat --out {dir}/out.toml";

BadInput ModelCase(std::string name, std::function<std::string(std::string)> edit, std::vector<std::string> expected) {
  expected.insert(expected.begin(), "bad.toml");
  return {"model", std::move(name),
          [edit](const fs::path& dir) { WriteBytes(dir / "bad.toml", edit(std::string(model::DefaultModelToml()))); },
          kModelCommand, std::move(expected)};
}

BadInput MatCase(std::string name, std::function<void(MatV5&)> edit, std::vector<std::string> expected) {
  expected.insert(expected.begin(), "bad.mat");
  return {"mat", std::move(name),
          [edit](const fs::path& dir) {
            MatV5 m = MatV5::Read(Synthesized(dir, "base.mat"));
            edit(m);
            m.Write(dir / "bad.mat");
          },
          kMatCommand, std::move(expected)};
}

BadInput MatBytesCase(std::string name, std::function<std::string(std::string)> edit,
                      std::vector<std::string> expected) {
  expected.insert(expected.begin(), "bad.mat");
  return {"mat", std::move(name),
          [edit](const fs::path& dir) { WriteBytes(dir / "bad.mat", edit(ReadBytes(Synthesized(dir, "base.mat")))); },
          kMatCommand, std::move(expected)};
}

// `edit` gets the measurement and the sidecar text and changes either.
BadInput CsvCase(std::string name, std::function<void(std::string&, std::string&)> edit,
                 std::vector<std::string> expected) {
  return {"csv", std::move(name),
          [edit](const fs::path& dir) {
            const fs::path base = Synthesized(dir, "base.csv");
            std::string csv = ReadBytes(base), sidecar = ReadBytes(dir / "base.geometry.csv");
            edit(csv, sidecar);
            WriteBytes(dir / "bad.csv", csv);
            WriteBytes(dir / "bad.geometry.csv", sidecar);
          },
          kCsvCommand, std::move(expected)};
}

BadInput UffCase(std::string name, std::function<std::string(std::string)> edit, std::vector<std::string> expected) {
  expected.insert(expected.begin(), "bad.uff");
  return {"uff", std::move(name), [edit](const fs::path& dir) { WriteBytes(dir / "bad.uff", edit(SmallUffText(dir))); },
          kUffCommand, std::move(expected)};
}

BadInput RawCase(std::string name, std::function<void(const fs::path& path)> make, std::vector<std::string> expected) {
  expected.insert(expected.begin(), "bad.mat");
  return {"raw", std::move(name), [make](const fs::path& dir) { make(dir / "bad.mat"); }, kRawCommand,
          std::move(expected)};
}

BadInput RecordCase(std::string name, std::function<std::string(std::string)> edit, std::vector<std::string> expected) {
  expected.insert(expected.begin(), "bad.csv");
  return {"record", std::move(name), [edit](const fs::path& dir) { WriteBytes(dir / "bad.csv", edit(RecordText())); },
          kRecordCommand, std::move(expected)};
}

BadInput RecipeCase(std::string name, std::function<std::string(std::string)> edit, std::vector<std::string> expected) {
  expected.insert(expected.begin(), "bad.toml");
  return {"recipe", std::move(name),
          [edit](const fs::path& dir) {
            Synthesized(dir, "base.mat");
            WriteBytes(dir / "bad.toml", edit(kRecipe));
          },
          kRecipeCommand, std::move(expected)};
}

BadInput WithCase(std::string name, std::string effect, std::vector<std::string> expected) {
  return {"with", std::move(name), [](const fs::path&) {},
          "model --report {dir}/out.json --with '" + effect + "'", std::move(expected)};
}

std::string NonUtf8(const std::string& s) { return s + "\xff\xfe"; }

std::vector<BadInput> ModelCases() {
  return {
      ModelCase("SyntaxError", [](std::string t) { return Edit(t, "[[body]]", "[[body]"); }, {"TOML syntax error"}),
      ModelCase("TruncatedInsideAString", [](std::string t) { return CutAfter(t, "mass = \"15"); },
                {"TOML syntax error", "string"}),
      ModelCase("TruncatedAfterTheBodies", [](std::string t) { return CutAfter(t, "note = \"estimate (SPEC §2)\"\n\n"); },
                {"body 'granite' is not connected to the ground"}),
      ModelCase("MassOfWrongType", [](std::string t) { return Edit(t, "mass = \"15 kg\"", "mass = true"); },
                {"body 'hexapod': mass", "must be a number or a string with a unit"}),
      ModelCase("MassInMetres", [](std::string t) { return Edit(t, "mass = \"15 kg\"", "mass = \"15 m\""); },
                {"body 'hexapod': mass", "15 m", "expected a mass"}),
      ModelCase("MassNaN", [](std::string t) { return Edit(t, "mass = \"15 kg\"", "mass = nan"); },
                {"body 'hexapod': mass", "nan", "finite"}),
      ModelCase("StiffnessInfinite", [](std::string t) { return Edit(t, "Dx = \"5e9 N/m\"", "Dx = inf"); },
                {"joint 'granite': stiffness.Dx", "inf", "finite"}),
      ModelCase("NegativeMass", [](std::string t) { return Edit(t, "mass = \"15 kg\"", "mass = \"-15 kg\""); },
                {"body 'hexapod': mass = -15 kg", "expected"}),
      ModelCase("ZeroMass", [](std::string t) { return Edit(t, "mass = \"15 kg\"", "mass = 0"); },
                {"body 'hexapod': mass = 0 kg", "expected a finite value > 0"}),
      ModelCase("NegativeStiffness", [](std::string t) { return Edit(t, "Dz = \"2e8 N/m\"", "Dz = \"-2e8 N/m\""); },
                {"joint 'ty': stiffness Dz = -2e+08", "expected a finite value >= 0"}),
      ModelCase("NegativeInertia", [](std::string t) { return Edit(t, "inertia = [0.09, 0.09, 0.17]", "inertia = [0.09, -0.09, 0.17]"); },
                {"body 'hexapod': inertia is not positive definite", "-0.09", "expected all > 0"}),
      ModelCase("ComWithTwoValues", [](std::string t) { return Edit(t, "com = [0.0, 0.0, -0.045]", "com = [0.0, -0.045]"); },
                {"body 'hexapod'", "'com' must be an array of 3 values"}),
      ModelCase("InertiaWithFourValues", [](std::string t) { return Edit(t, "inertia = [0.09, 0.09, 0.17]", "inertia = [0.09, 0.09, 0.17, 0.0]"); },
                {"body 'hexapod'", "'inertia' must be [Ixx, Iyy, Izz]"}),
      ModelCase("UnknownKey", [](std::string t) { return Edit(t, "mass = \"15 kg\"", "mass = \"15 kg\"\nmas = 3"); },
                {"body 'hexapod'", "unknown key 'mas'", "expected one of"}),
      ModelCase("MissingMass", [](std::string t) { return Edit(t, "mass = \"15 kg\"\n", ""); },
                {"body 'hexapod'", "'mass' is missing"}),
      ModelCase("UnknownDofImposed", [](std::string t) { return Edit(t, "imposed = [\"Dy\"]", "imposed = [\"Dq\"]"); },
                {"joint 'ty'", "'Dq'", "expected one of Dx, Dy, Dz, Rx, Ry, Rz"}),
      ModelCase("JointOnUnknownBody", [](std::string t) { return Edit(t, "parent = \"granite\"", "parent = \"granit\""); },
                {"joint 'ty': parent 'granit' is not a body of the model"}),
      ModelCase("NonUtf8Name", [](std::string t) { return Edit(t, "name = \"hexapod\"", "name = \"" + NonUtf8("hexapod") + "\""); },
                {"TOML syntax error", "invalid utf-8"}),
      ModelCase("NestingThatWouldExhaustTheStack",
                [](std::string t) { return t + "\n[model2]\nx = " + std::string(100000, '[') + std::string(100000, ']') + "\n"; },
                {"TOML syntax error", "nest"}),
  };
}

std::vector<BadInput> MatCases() {
  return {
      MatBytesCase("Truncated", [](std::string b) { return b.substr(0, b.size() / 2); },
                   {"declares", "bytes but only", "the file is truncated"}),
      MatBytesCase("NotAMatFile", [](std::string) { return std::string("freq_hz,frf\n1,2\n"); },
                   {"not a MATLAB .mat file", "shorter than the 128-byte header"}),
      MatBytesCase("TextWithAMatFileName", [](std::string) { return std::string(200, 'x') + "\n"; },
                   {"not a MATLAB .mat file", "header"}),
      MatCase("MissingFrf", [](MatV5& m) { m.Remove("frf"); }, {"variable 'frf' is missing", "Nout x Nin x Nf"}),
      MatCase("FrequenciesAsText", [](MatV5& m) { m.Put(Var("freq_hz", std::string("10 20 30"))); },
              {"variable 'freq_hz'", "is text, expected a numeric array"}),
      MatCase("FrequenciesComplex", [](MatV5& m) { m.Put(Var("freq_hz", Eigen::MatrixXcd::Constant(12, 1, {10.0, 1.0}))); },
              {"variable 'freq_hz'", "is complex, expected real values"}),
      MatCase("FrequencyCountDisagreesWithFrf",
              [](MatV5& m) { m.Put(Var("freq_hz", Eigen::MatrixXd(Eigen::VectorXd::LinSpaced(11, 10.0, 400.0)))); },
              {"variable 'frf'", "size 12 x 10 x 12", "expected Nout x Nin x 11"}),
      MatCase("FrequencyNaN", [](MatV5& m) { m.SetDouble("freq_hz", 3, kNaN); },
              {"freq_hz[4] = nan Hz", "expected a finite frequency > 0"}),
      MatCase("FrequencyNegative", [](MatV5& m) { m.SetDouble("freq_hz", 0, -10.0); },
              {"freq_hz[1] = -10 Hz", "expected a finite frequency > 0"}),
      MatCase("FrequencyZero", [](MatV5& m) { m.SetDouble("freq_hz", 0, 0.0); },
              {"freq_hz[1] = 0 Hz", "expected a finite frequency > 0"}),
      MatCase("FrequenciesNotIncreasing", [](MatV5& m) { m.SetDouble("freq_hz", 5, 1.0); },
              {"freq_hz[6] = 1 Hz", "expected strictly increasing"}),
      MatCase("FrfInfinite", [](MatV5& m) { m.SetDouble("frf", 7, kInf, 1); },
              {"frf(8, 1, 1)", "inf", "expected a finite value"}),
      MatCase("CoherenceAboveOne", [](MatV5& m) { m.SetDouble("coherence", 0, 1.5); },
              {"coherence(1, 1, 1) = 1.5", "expected a value in [0, 1]"}),
      MatCase("UnknownQuantity", [](MatV5& m) { m.Put(Var("quantity", std::string("inertance"))); },
              {"variable 'quantity'", "'inertance'", "expected 'accelerance', 'mobility' or 'receptance'"}),
      MatCase("HugeDeclaredSize", [](MatV5& m) { m.SetDim("frf", 2, 2000000000); },
              {"variable 2", "dimension 3 = 2000000000", "more than the file can hold"}),
      MatCase("HugeFrequencyCount", [](MatV5& m) { m.SetDim("freq_hz", 0, 2000000000); },
              {"variable 1", "dimension 1 = 2000000000", "more than the file can hold"}),
      MatCase("SizesWhoseProductIsBeyondTheFile",
              [](MatV5& m) {
                m.SetDim("coherence", 0, 30000);
                m.SetDim("coherence", 1, 30000);
              },
              {"coherence", "more than the file can hold"}),
      MatCase("NonUtf8ChannelName",
              [](MatV5& m) {
                std::vector<std::string> names = {"a1x", "a1y", "a1z", "a2x", "a2y", "a2z",
                                                  "a3x", "a3y", "a3z", "a4x", "a4y", "a4z"};
                names[2] = NonUtf8("a1z");
                m.Put(Var("output_names", names));
              },
              {"output 3", "'a1z\\xFF\\xFE' is not valid UTF-8"}),
      MatCase("OutputNamesWrongCount", [](MatV5& m) { m.Put(Var("output_names", std::vector<std::string>{"a", "b"})); },
              {"variable 'output_names'", "2 names, expected 12"}),
      MatCase("DuplicateChannelName",
              [](MatV5& m) {
                m.Put(Var("input_names", std::vector<std::string>{"h1", "h1", "h3", "h4", "h5", "h6", "h7", "h8", "h9", "h10"}));
              },
              {"input 2", "'h1' is used twice", "expected unique names"}),
      MatCase("SensorPositionsWrongSize", [](MatV5& m) { m.Put(Var("sensor_position", Eigen::MatrixXd::Zero(11, 3))); },
              {"variable 'sensor_position'", "size 11 x 3", "expected 12 x 3"}),
      MatCase("SensorDirectionZero", [](MatV5& m) { m.SetDouble("sensor_direction", 0, 0.0); },
              {"output 1", "direction has length", "expected a unit vector"}),
      MatCase("PartialGeometry", [](MatV5& m) { m.Remove("impact_direction"); },
              {"missing geometry", "'impact_direction'"}),
  };
}

std::vector<BadInput> CsvCases() {
  auto line = [](const std::string& text, int n) {  // n-th data line (0-based) after the header
    std::size_t at = text.find("freq_hz,");
    for (int i = 0; i <= n; ++i) at = text.find('\n', at) + 1;
    return at;
  };
  return {
      CsvCase("WrongHeader", [](std::string& c, std::string&) { c = Edit(c, "freq_hz,output", "frequency,output"); },
              {"bad.csv", "line 1", "header", "expected 'freq_hz,output,input,re,im'"}),
      CsvCase("TruncatedInsideARow",
              [line](std::string& c, std::string&) { c = c.substr(0, c.find(',', c.find(',', line(c, 40)) + 1)); },
              {"bad.csv", "line 42", "2 fields, expected 6"}),
      CsvCase("NotANumber",
              [line](std::string& c, std::string&) {
                const std::size_t at = line(c, 3);
                c = c.substr(0, at) + "10,a1x,h1,abc,0,0.9\n" + c.substr(line(c, 4));
              },
              {"bad.csv", "line 5", "column 're': 'abc' is not a number"}),
      CsvCase("ImaginaryPartNaN",
              [line](std::string& c, std::string&) {
                const std::size_t at = line(c, 3);
                c = c.substr(0, at) + "10,a1x,h1,1e-3,nan,0.9\n" + c.substr(line(c, 4));
              },
              {"bad.csv", "line 5", "column 'im'", "nan", "expected a finite number"}),
      CsvCase("RealPartInfinite",
              [line](std::string& c, std::string&) {
                const std::size_t at = line(c, 3);
                c = c.substr(0, at) + "10,a1x,h1,inf,0,0.9\n" + c.substr(line(c, 4));
              },
              {"bad.csv", "line 5", "column 're'", "inf", "expected a finite number"}),
      CsvCase("NegativeFrequency",
              [](std::string& c, std::string&) {
                // The first frequency of every pair becomes -10 Hz (still increasing within a pair).
                for (std::size_t at = 0; (at = c.find("\n10,", at)) != std::string::npos; at += 2) c.insert(at + 1, "-");
              },
              {"bad.csv", "freq_hz[1] = -10 Hz", "expected a finite frequency > 0"}),
      CsvCase("CoherenceAboveOne",
              [line](std::string& c, std::string&) {
                const std::size_t at = line(c, 0);
                const std::size_t end = c.find('\n', at);
                const std::string row = c.substr(at, end - at);
                c = c.substr(0, at) + row.substr(0, row.rfind(',')) + ",1.5" + c.substr(end);
              },
              {"bad.csv", "line 2", "column 'coherence': 1.5", "expected a value in [0, 1]"}),
      CsvCase("RepeatedRow",
              [line](std::string& c, std::string&) {
                const std::size_t at = line(c, 1);
                const std::string row = c.substr(at, line(c, 2) - at);
                c.insert(at, row);
              },
              {"bad.csv", "line 4", "expected strictly increasing frequencies"}),
      CsvCase("MissingPair",
              [line](std::string& c, std::string&) {
                // The first output-input pair is the first 12 rows: drop them.
                c = c.substr(0, line(c, 0)) + c.substr(line(c, 12));
              },
              {"bad.csv", "no rows for output 'a1x' and input 'h1'"}),
      CsvCase("UnterminatedQuote",
              [line](std::string& c, std::string&) { c.insert(line(c, 2), "10,\"a1x,h1,1,0,0.9\n"); },
              {"bad.csv", "line 4", "unterminated double quote"}),
      // The sidecar of a header-first CSV (common/csv_meta.h): not JSON, or a quantity it cannot be.
      BadInput{"csv", "MetaNotJson",
               [](const fs::path& dir) {
                 const fs::path base = Synthesized(dir, "base.csv");
                 WriteBytes(dir / "bad.csv", ReadBytes(base));
                 WriteBytes(dir / "bad.geometry.csv", ReadBytes(dir / "base.geometry.csv"));
                 WriteBytes(dir / "bad.meta.json", "{\"quantity\": \"accelerance\", ");
               },
               kCsvCommand, {"bad.meta.json", "not a JSON object"}},
      BadInput{"csv", "MetaUnknownQuantity",
               [](const fs::path& dir) {
                 const fs::path base = Synthesized(dir, "base.csv");
                 WriteBytes(dir / "bad.csv", ReadBytes(base));
                 WriteBytes(dir / "bad.geometry.csv", ReadBytes(dir / "base.geometry.csv"));
                 WriteBytes(dir / "bad.meta.json", "{\"quantity\": \"velocity\", \"units\": {}}");
               },
               kCsvCommand, {"bad.meta.json", "quantity 'velocity'", "expected accelerance, mobility"}},
      CsvCase("TooManyChannelsForItsRows",
              [](std::string& c, std::string&) {
                // 40,000 distinct outputs and inputs in as many rows would need 1.6e9 pairs (and as
                // many rows): the reader must refuse before allocating the pair table.
                c = "freq_hz,output,input,re,im\n";
                for (int i = 0; i < 40000; ++i) c += "10,o" + std::to_string(i) + ",i" + std::to_string(i) + ",1,0\n";
              },
              {"bad.csv", "line 202", "201 outputs and 201 inputs", "need at least 40401 rows", "only 40001 lines"}),
      CsvCase("NonUtf8ChannelName",
              [](std::string& c, std::string& s) {
                std::string out;
                for (std::size_t at = 0, e; (e = c.find('\n', at)) != std::string::npos; at = e + 1) {
                  std::string l = c.substr(at, e - at);
                  const std::size_t p = l.find(",a1x,");
                  if (p != std::string::npos) l.replace(p, 5, "," + NonUtf8("a1x") + ",");
                  out += l + "\n";
                }
                c = out;
                s = Edit(s, "sensor,a1x,", "sensor," + NonUtf8("a1x") + ",");
              },
              {"bad.csv", "output 1: channel name 'a1x\\xFF\\xFE' is not valid UTF-8"}),
      CsvCase("SidecarDirectionNotUnit",
              [](std::string&, std::string& s) { s = ReplaceLine(s, "sensor,a1x,", 0, "sensor,a1x,hexapod,0,0.14,0,2,0,0"); },
              {"bad.geometry.csv", "line 2", "sensor 'a1x'", "length 2", "expected a unit vector"}),
      CsvCase("SidecarPositionNaN",
              [](std::string&, std::string& s) { s = ReplaceLine(s, "sensor,a1x,", 0, "sensor,a1x,hexapod,nan,0.14,0,1,0,0"); },
              {"bad.geometry.csv", "line 2", "column 'x'", "nan", "expected a finite number"}),
      CsvCase("SidecarUnknownKind",
              [](std::string&, std::string& s) { s = Edit(s, "sensor,a1x,", "probe,a1x,"); },
              {"bad.geometry.csv", "line 2", "'probe'", "expected 'sensor' or 'impact'"}),
      CsvCase("SidecarUnknownChannel",
              [](std::string&, std::string& s) { s = Edit(s, "sensor,a1x,", "sensor,a9x,"); },
              {"bad.geometry.csv", "line 2", "sensor 'a9x' is not an output"}),
      CsvCase("SidecarWrongFieldCount",
              [](std::string&, std::string& s) { s = ReplaceLine(s, "sensor,a1x,", 0, "sensor,a1x,hexapod,0,0.14,0,1,0"); },
              {"bad.geometry.csv", "line 2", "8 fields, expected 9"}),
  };
}

std::vector<BadInput> UffCases() {
  // Line numbers of the small file: 1 "-1", 2 "58", 3-7 records 1-5, 8 record 6, 9 record 7,
  // 10-13 records 8-11, 14-25 the 12 data lines, 26 "-1"; the second dataset follows.
  auto cut_lines = [](const std::string& t, int lines) {
    std::size_t at = 0;
    for (int i = 0; i < lines; ++i) at = t.find('\n', at) + 1;
    return t.substr(0, at);
  };
  auto record7 = [](const std::string& t) {
    const std::size_t at = t.find("\n         6") + 1;
    return std::make_pair(at, t.find('\n', at));
  };
  return {
      UffCase("TruncatedInsideTheData", [cut_lines](std::string t) { return cut_lines(t, 20); }, {"truncated"}),
      UffCase("TruncatedInsideTheHeader", [cut_lines](std::string t) { return cut_lines(t, 8); },
              {"ends inside its header", "record 7 is missing"}),
      UffCase("MissingClosingDelimiter", [cut_lines](std::string t) { return cut_lines(t, 25); },
              {"without the closing '-1' delimiter"}),
      UffCase("PointCountThatWouldExhaustMemory",
              [record7](std::string t) {
                auto [b, e] = record7(t);
                return t.substr(0, b) + "         6999999999         0  0.00000E+00  0.00000E+00  0.00000E+00" + t.substr(e);
              },
              {"line 9", "record 7 declares 999999999 points", "the file is truncated or the count is corrupt"}),
      UffCase("NegativePointCount",
              [record7](std::string t) {
                auto [b, e] = record7(t);
                return t.substr(0, b) + "         6       -12         0  0.00000E+00  0.00000E+00  0.00000E+00" + t.substr(e);
              },
              {"line 9", "number of points", "-12", "expected at least 1"}),
      UffCase("UnknownOrdinateType",
              [record7](std::string t) {
                auto [b, e] = record7(t);
                return t.substr(0, b) + "         7        12         0  0.00000E+00  0.00000E+00  0.00000E+00" + t.substr(e);
              },
              {"line 9", "ordinate data type", "7", "expected 2 (real single)"}),
      UffCase("EvenSpacingWithZeroIncrement",
              [record7](std::string t) {
                auto [b, e] = record7(t);
                return t.substr(0, b) + "         6        12         1  1.00000E+01  0.00000E+00  0.00000E+00" + t.substr(e);
              },
              {"line 9", "abscissa increment", "expected > 0 with even spacing"}),
      UffCase("DataValueNotANumber", [](std::string t) { return ReplaceLine(t, "  1.00000E+01", 0, "  1.00000E+01  abc  1.0"); },
              {"line 14", "abc", "expected a real number"}),
      UffCase("DataValueNaN",
              [](std::string t) { return ReplaceLine(t, "  1.00000E+01", 0, "  1.00000E+01                 NaN  1.000000000000E-03"); },
              {"line 14", "not finite", "expected a finite real number"}),
      UffCase("MoreValuesThanDeclared",
              [](std::string t) {
                return ReplaceLine(t, "  1.00000E+01", 0, "  1.00000E+01  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0  1.0");
              },
              {"more data values than the 12 points declared"}),
      UffCase("BadDatasetNumber", [](std::string t) { return Edit(t, "    58\n", "    5x\n"); },
              {"line 2", "5x", "expected a dataset number"}),
      UffCase("BinaryByteCountThatWouldExhaustMemory",
              [](std::string t) { return Edit(t, "    58\n", "    58b     1     2    11 99999999999     0     0     0     0\n"); },
              {"58b header declares 99999999999 bytes"}),
      UffCase("DuplicateFrf",
              [](std::string t) {
                const std::size_t second = t.find("    -1\n    58\n", 10);
                return t + t.substr(0, second);
              },
              {"a second FRF for this response/reference pair"}),
      UffCase("NoFrfRecord",
              [](std::string t) {
                // Function type 4 (FRF) in record 6 becomes 1 (time response) in both datasets.
                for (int n = 0; n < 2; ++n) {
                  const std::size_t at = t.find("\n    4         0");
                  t.replace(at, 6, "\n    1");
                }
                return t;
              },
              {"no FRF record"}),
      UffCase("DirectionCodeOutOfRange",
              [](std::string t) {
                const std::size_t at = t.find("\n    4         0") + 1;
                const std::size_t e = t.find('\n', at);
                std::string line = t.substr(at, e - at);
                line.replace(line.rfind("-2"), 2, " 9");
                return t.substr(0, at) + line + t.substr(e);
              },
              {"direction code 9"}),
  };
}

std::vector<BadInput> RawCases() {
  return {
      RawCase("Truncated",
              [](const fs::path& p) {
                WriteRaw(p, RawVariables());
                const std::string b = ReadBytes(p);
                WriteBytes(p, b.substr(0, b.size() / 2));
              },
              {"declares", "bytes but only", "the file is truncated"}),
      RawCase("NotAMatFile", [](const fs::path& p) { WriteBytes(p, "time,force\n0,1\n"); },
              {"not a MATLAB .mat file", "shorter than the 128-byte header"}),
      RawCase("MissingSampleRate",
              [](const fs::path& p) {
                auto v = RawVariables();
                v.erase(v.begin());
                WriteRaw(p, v);
              },
              {"sample_rate_hz: missing, expected this variable"}),
      RawCase("SampleRateZero", [](const fs::path& p) { WriteRawWith(p, Var("sample_rate_hz", Eigen::MatrixXd::Zero(1, 1))); },
              {"sample_rate_hz = 0", "expected a finite rate > 0 Hz"}),
      RawCase("SampleRateNegative",
              [](const fs::path& p) { WriteRawWith(p, Var("sample_rate_hz", Eigen::MatrixXd::Constant(1, 1, -1024.0))); },
              {"sample_rate_hz = -1024", "expected a finite rate > 0 Hz"}),
      RawCase("SampleRateNaN", [](const fs::path& p) { WriteRawWith(p, Var("sample_rate_hz", Eigen::MatrixXd::Constant(1, 1, kNaN))); },
              {"sample_rate_hz = nan", "expected a finite rate > 0 Hz"}),
      RawCase("SampleRateAsVector",
              [](const fs::path& p) { WriteRawWith(p, Var("sample_rate_hz", Eigen::MatrixXd::Constant(1, 2, 1024.0))); },
              {"sample_rate_hz", "size 1 x 2", "expected 1 x 1"}),
      RawCase("ForceNaN",
              [](const fs::path& p) {
                Eigen::MatrixXd f = RawMatrix("force");
                f(100, 0) = kNaN;
                WriteRawWith(p, Var("force", f));
              },
              {"force", "NaN or Inf"}),
      RawCase("ResponseInfinite",
              [](const fs::path& p) {
                Eigen::MatrixXd r = RawMatrix("response");
                r(200, 1) = kInf;
                WriteRawWith(p, Var("response", r));
              },
              {"response", "'a2'", "NaN or Inf"}),
      RawCase("ResponseShorterThanForce",
              [](const fs::path& p) { WriteRawWith(p, Var("response", Eigen::MatrixXd(RawMatrix("response").topRows(500)))); },
              {"response", "size 500 x 2", "expected Ns x Nout x Nhits x Nin = 512 x Nout x 1 x 1"}),
      RawCase("ForceAllZero", [](const fs::path& p) { WriteRawWith(p, Var("force", Eigen::MatrixXd::Zero(512, 1))); },
              {"force", "all samples are zero, expected an impact"}),
      RawCase("DeadResponseChannel",
              [](const fs::path& p) {
                Eigen::MatrixXd r = RawMatrix("response");
                r.col(1).setZero();
                WriteRawWith(p, Var("response", r));
              },
              {"'a2'", "dead channel"}),
      RawCase("RecordsTooShort",
              [](const fs::path& p) {
                auto v = RawVariables();
                v[1].value = Eigen::MatrixXd(RawMatrix("force").topRows(8));
                v[2].value = Eigen::MatrixXd(RawMatrix("response").topRows(8));
                WriteRaw(p, v);
              },
              {"records of 8 samples, expected at least 16"}),
      RawCase("UnknownResponseQuantity", [](const fs::path& p) { WriteRawWith(p, Var("response_quantity", std::string("jerk"))); },
              {"response_quantity", "\"jerk\"", "expected \"acceleration\", \"velocity\" or \"displacement\""}),
      RawCase("ResponseQuantityNumeric",
              [](const fs::path& p) { WriteRawWith(p, Var("response_quantity", Eigen::MatrixXd::Ones(1, 1))); },
              {"response_quantity", "expected a char row vector"}),
      RawCase("OutputNamesWrongCount",
              [](const fs::path& p) { WriteRawWith(p, Var("output_names", std::vector<std::string>{"a1", "a2", "a3"})); },
              {"output_names", "expected 2 elements"}),
      RawCase("NonUtf8OutputName",
              [](const fs::path& p) { WriteRawWith(p, Var("output_names", std::vector<std::string>{"a1", NonUtf8("a2")})); },
              {"output_names(2)", "'a2\\xFF\\xFE' is not valid UTF-8"}),
      RawCase("NegativeFullScale",
              [](const fs::path& p) { WriteRawWith(p, Var("force_full_scale_n", Eigen::MatrixXd::Constant(1, 1, -500.0))); },
              {"force_full_scale_n", "-500", "expected finite ranges >= 0"}),
      RawCase("ForceComplex",
              [](const fs::path& p) { WriteRawWith(p, Var("force", Eigen::MatrixXcd(RawMatrix("force").cast<std::complex<double>>()))); },
              {"force", "complex, expected real values"}),
      RawCase("SizeThatWouldExhaustMemory",
              [](const fs::path& p) {
                WriteRaw(p, RawVariables());
                MatV5::Read(p).SetDim("response", 1, 2000000000).Write(p);
              },
              {"variable 3", "dimension 2 = 2000000000", "more than the file can hold"}),
      RawCase("SizeBeyondTheFile",
              [](const fs::path& p) {
                // 2^27 samples pass the total-size limit but cannot be in a 13 kB file.
                WriteRaw(p, RawVariables());
                MatV5::Read(p).SetDim("response", 0, 1 << 26).Write(p);
              },
              {"variable 3", "dimension 1 = 67108864", "more than the file can hold"}),
      RawCase("SizesWhoseProductIsBeyondTheFile",
              [](const fs::path& p) {
                // Each dimension alone could be held (compressed), and 1e8 values are within the
                // total-size limit, but not in a 13 kB file.
                WriteRaw(p, RawVariables());
                MatV5::Read(p).SetDim("response", 0, 10000).SetDim("response", 1, 10000).Write(p);
              },
              {"response: size 10000 x 10000 x 1 x 1 (100000000 values)", "more than the file can hold"}),
  };
}

std::vector<BadInput> RecordCases() {
  return {
      RecordCase("Empty", [](std::string) { return std::string(); }, {"no header line"}),
      RecordCase("HeaderOnly", [](std::string t) { return CutAfter(t, "time_s,v\n"); },
                 {"column 'time_s': 0 rows, expected at least 2"}),
      RecordCase("TruncatedInsideARow", [](std::string t) { return CutAfter(t, "\n1.000000,"); },
                 {"bad.csv:105", "column 'v': ''", "expected a finite number"}),
      RecordCase("RowWithExtraField", [](std::string t) { return Edit(t, "\n0.050000,", "\n0.050000,1,"); },
                 {"bad.csv:10", "3 fields, expected 2"}),
      RecordCase("NotANumber", [](std::string t) { return ReplaceLine(t, "0.050000,", 0, "0.050000,1.2.3"); },
                 {"bad.csv:10", "column 'v': '1.2.3'", "expected a finite number"}),
      RecordCase("ValueNaN", [](std::string t) { return ReplaceLine(t, "0.050000,", 0, "0.050000,nan"); },
                 {"bad.csv:10", "column 'v': 'nan'", "expected a finite number"}),
      RecordCase("TimeInfinite", [](std::string t) { return ReplaceLine(t, "0.050000,", 0, "inf,0"); },
                 {"bad.csv:10", "column 'time_s': 'inf'", "expected a finite number"}),
      RecordCase("FirstColumnNotTime", [](std::string t) { return Edit(Edit(t, "time_s,v", "t,v"), "# unit time_s s\n", ""); },
                 {"no column 'time_s'"}),
      RecordCase("RepeatedColumn", [](std::string t) { return Edit(t, "time_s,v", "time_s,v,v"); },
                 {"header column 'v' is empty or repeated"}),
      RecordCase("TimeNotIncreasing", [](std::string t) {
                   std::string out = "time_s,v\n";
                   for (int i = 0; i < 64; ++i) out += std::to_string(1.0 - i * 0.01) + ",0.001\n";
                   return out;
                 },
                 {"column 'time_s' does not increase"}),
      RecordCase("TimeWithAGap", [](std::string t) { return ReplaceLine(t, "0.050000,", 0, "0.055000,0"); },
                 {"column 'time_s'", "step", "expected even steps"}),
      RecordCase("VoltageInMillivolts", [](std::string t) { return Edit(t, "# unit v V", "# unit v mV"); },
                 {"column 'v' is declared in 'mV'", "expected SI values in 'V'"}),
      RecordCase("UnitLineForNoColumn", [](std::string t) { return Edit(t, "# unit v V", "# unit w V"); },
                 {"unit line for 'w', which is not a column"}),
      RecordCase("NonUtf8ColumnName",
                 [](std::string t) { return Edit(Edit(t, "time_s,v", "time_s," + NonUtf8("v")), "# unit v V\n", ""); },
                 {"bad.csv:3", "header column 'v\\xFF\\xFE' is not valid UTF-8"}),
  };
}

std::vector<BadInput> RecipeCases() {
  return {
      RecipeCase("SyntaxError", [](std::string t) { return Edit(t, "[[bounds]]", "[[bounds]"); }, {"syntax"}),
      RecipeCase("Truncated", [](std::string t) { return CutAfter(t, "solver = \"cer"); }, {"syntax"}),
      RecipeCase("UnknownKey", [](std::string t) { return Edit(t, "seed = 1", "sede = 1"); },
                 {"sede", "unknown key", "expected one of"}),
      RecipeCase("UnknownSolver", [](std::string t) { return Edit(t, "solver = \"ceres\"", "solver = \"magic\""); },
                 {"solver = 'magic'", "expected ceres or nlopt"}),
      RecipeCase("StartsZero", [](std::string t) { return Edit(t, "starts = 1", "starts = 0"); },
                 {"starts = 0", "expected an integer >= 1"}),
      RecipeCase("IterationsNegative", [](std::string t) { return Edit(t, "max_iterations = 2", "max_iterations = -5"); },
                 {"max_iterations = -5", "expected an integer >= 1"}),
      RecipeCase("StartsThatWouldExhaustMemory", [](std::string t) { return Edit(t, "starts = 1", "starts = 1000000000000"); },
                 {"starts = 1000000000000", "expected an integer >= 1 and <= 2147483647"}),
      RecipeCase("IterationsAsText", [](std::string t) { return Edit(t, "max_iterations = 2", "max_iterations = \"many\""); },
                 {"max_iterations", "many", "expected an integer"}),
      RecipeCase("BandReversed", [](std::string t) { return Edit(t, "[\"10 Hz\", \"400 Hz\"]", "[\"400 Hz\", \"10 Hz\"]"); },
                 {"band", "expected 0 <= low < high"}),
      RecipeCase("BandInKilograms", [](std::string t) { return Edit(t, "\"400 Hz\"", "\"400 kg\""); },
                 {"band", "400 kg", "frequency"}),
      RecipeCase("StartFactorNaN", [](std::string t) { return Edit(t, "start_factor = 1.6", "start_factor = nan"); },
                 {"start_factor = nan", "expected a number >= 1"}),
      RecipeCase("BoundFactorZero", [](std::string t) { return Edit(t, "factor = 10", "factor = 0"); },
                 {"bounds", "factor", "0"}),
      RecipeCase("BoundLowerAboveUpper",
                 [](std::string t) { return Edit(t, "factor = 10", "lower = \"10 N/um\"\nupper = \"1 N/um\""); },
                 {"bounds", "lower", "> upper, expected lower <= upper"}),
      RecipeCase("NonUtf8Pattern", [](std::string t) { return Edit(t, "\"hexapod.k.Dz\"", "\"" + NonUtf8("hexapod.k.Dz") + "\""); },
                 {"syntax", "invalid utf-8"}),
  };
}

std::vector<BadInput> WithCases() {
  return {
      WithCase("UnknownEffect", "nosuch@hexapod", {"nosuch", "is not in the catalogue"}),
      WithCase("UnknownLocation", "payload@moon", {"'moon' is not a location of payload"}),
      WithCase("NoLocation", "payload", {"--with 'payload'", "expected EFFECT@LOCATION"}),
      WithCase("NegativeMass", "payload@hexapod:mass=-5", {"payload", "mass = -5", "expected a value in [0"}),
      WithCase("MassNaN", "payload@hexapod:mass=nan", {"mass = 'nan'", "expected a finite number"}),
      WithCase("MassInMetres", "payload@hexapod:mass=5 m", {"mass = '5 m'", "expected a mass"}),
      WithCase("UnknownParameter", "payload@hexapod:colour=red", {"payload has no parameter 'colour'"}),
      WithCase("ParameterWithoutValue", "payload@hexapod:mass", {"'mass' should be name=value"}),
  };
}

std::vector<BadInput> AllCases() {
  std::vector<BadInput> all;
  for (auto list : {ModelCases(), MatCases(), CsvCases(), UffCases(), RawCases(), RecordCases(), RecipeCases(),
                    WithCases()}) {
    all.insert(all.end(), list.begin(), list.end());
  }
  return all;
}

std::set<std::string> FilesIn(const fs::path& dir) {
  std::set<std::string> names;
  for (const auto& e : fs::recursive_directory_iterator(dir)) names.insert(fs::relative(e.path(), dir).string());
  return names;
}

#if defined(__SANITIZE_ADDRESS__)
#define STAGEFIT_TEST_UNDER_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define STAGEFIT_TEST_UNDER_ASAN 1
#endif
#endif

// A reader that allocated by a declared size would exhaust the machine's memory: the runs get at most
// 4 GiB of address space (inherited by the program), so that such a regression fails with "out of
// memory" instead. Not under AddressSanitizer, which reserves far more address space at start.
void LimitAddressSpace() {
#ifndef STAGEFIT_TEST_UNDER_ASAN
  constexpr rlim_t kLimitBytes = rlim_t{4} << 30;
  rlimit limit{};
  if (::getrlimit(RLIMIT_AS, &limit) == 0 && (limit.rlim_cur == RLIM_INFINITY || limit.rlim_cur > kLimitBytes)) {
    limit.rlim_cur = kLimitBytes;
    ::setrlimit(RLIMIT_AS, &limit);
  }
#endif
}

class BadInputTest : public ::testing::TestWithParam<BadInput> {};

TEST_P(BadInputTest, ExitsTwoNamingTheProblemAndWritesNothing) {
  const BadInput& c = GetParam();
  LimitAddressSpace();
  const fs::path dir = TempDir("bad_" + c.reader + "_" + c.name);
  ASSERT_NO_THROW(c.make(dir));
  const std::set<std::string> before = FilesIn(dir);
  const auto r = RunStagefit(Substitute(c.command, dir));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  for (const std::string& fragment : c.expected) {
    EXPECT_NE(r.output.find(fragment), std::string::npos) << "missing '" << fragment << "' in:\n" << r.output;
  }
  EXPECT_EQ(FilesIn(dir), before) << "the failing command left files behind";
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(Readers, BadInputTest, ::testing::ValuesIn(AllCases()),
                         [](const ::testing::TestParamInfo<BadInput>& info) {
                           return info.param.reader + "_" + info.param.name;
                         });

// The controls: the same commands on the unmodified inputs succeed (so the bad cases fail because of
// their defect, not because of the command line or the base file).

TEST(BadInputControl, ValidModelIsAccepted) {
  const fs::path dir = TempDir("bad_control_model");
  WriteBytes(dir / "bad.toml", std::string(model::DefaultModelToml()));
  const auto r = RunStagefit(Substitute(kModelCommand, dir));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir / "out.json"));
}

TEST(BadInputControl, ValidMatMeasurementRoundTripsThroughTheEditor) {
  const fs::path dir = TempDir("bad_control_mat");
  MatV5 m = MatV5::Read(Synthesized(dir, "base.mat"));
  m.Put(Var("quantity", std::string("accelerance")));  // the editor's Put keeps the file valid
  m.Write(dir / "bad.mat");
  const auto r = RunStagefit(Substitute(kMatCommand, dir));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir / "out.json"));
}

TEST(BadInputControl, ValidCsvMeasurementIsAccepted) {
  const fs::path dir = TempDir("bad_control_csv");
  Synthesized(dir, "bad.csv");
  const auto r = RunStagefit(Substitute(kCsvCommand, dir));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir / "out.json"));
}

TEST(BadInputControl, ValidUffMeasurementIsAccepted) {
  const fs::path dir = TempDir("bad_control_uff");
  WriteBytes(dir / "bad.uff", SmallUffText(dir));
  const auto r = RunStagefit(Substitute(kUffCommand, dir));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir / "out.csv"));
}

TEST(BadInputControl, ValidRawDataIsAccepted) {
  const fs::path dir = TempDir("bad_control_raw");
  WriteRaw(dir / "bad.mat", RawVariables());
  const auto r = RunStagefit(Substitute(kRawCommand, dir));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir / "out.mat"));
}

TEST(BadInputControl, ValidRecordIsAccepted) {
  const fs::path dir = TempDir("bad_control_record");
  WriteBytes(dir / "bad.csv", RecordText());
  const auto r = RunStagefit(Substitute(kRecordCommand, dir));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir / "out.csv"));
}

TEST(BadInputControl, ValidRecipeIsAccepted) {
  const fs::path dir = TempDir("bad_control_recipe");
  Synthesized(dir, "base.mat");
  WriteBytes(dir / "bad.toml", kRecipe);
  const auto r = RunStagefit(Substitute(kRecipeCommand, dir));
  EXPECT_TRUE(r.exit_code == 0 || r.exit_code == 3) << r.output;  // 3: not converged in 2 iterations
  EXPECT_TRUE(fs::exists(dir / "out.toml"));
}

TEST(BadInputControl, ValidEffectIsAccepted) {
  const fs::path dir = TempDir("bad_control_with");
  const auto r = RunStagefit(Substitute("model --report {dir}/out.json --with 'payload@hexapod:mass=5 kg'", dir));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir / "out.json"));
}

// Text that is not UTF-8 may still come from a file's name: the report (JSON, which must be UTF-8)
// is written all the same, with U+FFFD in place of the bad bytes.
TEST(BadInputControl, NonUtf8FileNameStillGetsAReport) {
  const fs::path dir = TempDir("bad_control_file_name");
  const fs::path record = dir / (NonUtf8("record") + ".csv");
  WriteBytes(record, RecordText());
  const auto r = RunStagefit("disturbance psd '" + record.string() + "' --out " + (dir / "out.csv").string() +
                             " --report " + (dir / "out.json").string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(ReadBytes(dir / "out.json").find("record\xEF\xBF\xBD"), std::string::npos);
}

}  // namespace
}  // namespace stagefit
