#include "state_space_export.h"

#include <cstdio>
#include <filesystem>
#include <sstream>

#include "stagefit/common/atomic_file.h"
#include "stagefit/common/csv_meta.h"
#include "stagefit/common/error.h"

namespace stagefit::cli {
namespace {

std::string MatrixCsv(const Eigen::MatrixXd& m, const std::vector<std::string>& rows,
                      const std::vector<std::string>& cols) {
  std::ostringstream out;
  out << "name";
  for (const auto& c : cols) out << "," << c;
  out << "\n";
  char buffer[40];
  for (int r = 0; r < m.rows(); ++r) {
    out << rows[r];
    for (int c = 0; c < m.cols(); ++c) {
      std::snprintf(buffer, sizeof buffer, ",%.17g", m(r, c));
      out << buffer;
    }
    out << "\n";
  }
  return out.str();
}

std::string CsvPath(const std::string& out, const char* suffix) {
  std::filesystem::path stem(out);
  if (stem.extension() == ".csv") stem.replace_extension();
  return stem.string() + "_" + suffix + ".csv";
}

}  // namespace

std::vector<std::string> WriteStateSpaceCsv(const std::string& out, const model::StateSpace& ss,
                                            const model::SecondOrderSystem& sys) {
  struct Item {
    const char* suffix;
    const Eigen::MatrixXd* m;
    const std::vector<std::string>* rows;
    const std::vector<std::string>* cols;
  };
  const Item items[] = {{"A", &ss.A, &ss.state_names, &ss.state_names},
                        {"B", &ss.B, &ss.state_names, &ss.input_names},
                        {"C", &ss.C, &ss.output_names, &ss.state_names},
                        {"D", &ss.D, &ss.output_names, &ss.input_names},
                        {"M", &sys.M, &sys.dof_names, &sys.dof_names},
                        {"C_damping", &sys.C, &sys.dof_names, &sys.dof_names},
                        {"K", &sys.K, &sys.dof_names, &sys.dof_names}};
  std::vector<std::string> written;
  for (const auto& item : items) {
    std::string path = CsvPath(out, item.suffix);
    WriteFileAtomically(path, MatrixCsv(*item.m, *item.rows, *item.cols));
    CsvMeta meta;
    meta.fields["matrix"] = item.suffix;
    meta.units = {{"name", ""}};
    meta.notes = {std::string("rows: the first column (name); columns: the header. SI units of each entry follow "
                              "from its row and column (states q in m or rad and q' in m/s or rad/s; inputs N, Nm "
                              "or m; outputs m or rad): docs/model.md")};
    WriteCsvMeta(path, meta);
    written.push_back(path);
  }
  return written;
}

std::vector<std::string> WriteStateSpaceMat(const std::string& out, const model::StateSpace& ss,
                                            const model::SecondOrderSystem& sys);

std::vector<std::string> StateSpaceFiles(const std::string& out) {
  if (std::filesystem::path(out).extension() == ".mat") return {out};
  std::vector<std::string> files;
  for (const char* suffix : {"A", "B", "C", "D", "M", "C_damping", "K"}) files.push_back(CsvPath(out, suffix));
  return files;
}

std::vector<std::string> WriteStateSpace(const std::string& out, const model::StateSpace& ss,
                                         const model::SecondOrderSystem& sys) {
  if (std::filesystem::path(out).extension() == ".mat") return WriteStateSpaceMat(out, ss, sys);
  return WriteStateSpaceCsv(out, ss, sys);
}

}  // namespace stagefit::cli
