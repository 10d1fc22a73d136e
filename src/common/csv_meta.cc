#include "stagefit/common/csv_meta.h"

#include <nlohmann/json.hpp>

#include <fstream>
#include <sstream>

#include "stagefit/common/atomic_file.h"
#include "stagefit/common/error.h"

namespace stagefit {

std::filesystem::path CsvMetaPath(const std::filesystem::path& csv_path) {
  std::filesystem::path stem = csv_path;
  if (stem.extension() == ".csv" || stem.extension() == ".CSV") stem.replace_extension();
  stem += ".meta.json";
  return stem;
}

void WriteCsvMeta(const std::filesystem::path& csv_path, const CsvMeta& meta) {
  nlohmann::ordered_json j;
  j["file"] = csv_path.filename().string();
  for (const auto& [key, value] : meta.fields) j[key] = value;
  if (!meta.frame_origin_m.empty()) j["frame_origin_m"] = meta.frame_origin_m;
  if (!meta.num_averages.empty()) j["num_averages"] = meta.num_averages;
  nlohmann::ordered_json units = nlohmann::ordered_json::object();
  for (const auto& [column, unit] : meta.units) units[column] = unit;
  j["units"] = units;
  if (!meta.notes.empty()) j["notes"] = meta.notes;
  WriteFileAtomically(CsvMetaPath(csv_path), j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n");
}

std::optional<CsvMeta> ReadCsvMeta(const std::filesystem::path& csv_path) {
  const std::filesystem::path path = CsvMetaPath(csv_path);
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return std::nullopt;
  std::ifstream in(path);
  if (!in) throw InputError("'" + path.string() + "': cannot be opened");
  std::stringstream text;
  text << in.rdbuf();
  nlohmann::ordered_json j = nlohmann::ordered_json::parse(text.str(), nullptr, false);
  if (j.is_discarded() || !j.is_object()) {
    throw InputError("'" + path.string() + "': not a JSON object (the sidecar of '" + csv_path.string() + "')");
  }
  CsvMeta meta;
  for (auto it = j.begin(); it != j.end(); ++it) {
    const std::string& key = it.key();
    if (key == "units") {
      if (!it->is_object()) throw InputError("'" + path.string() + "': units: expected an object {column: unit}");
      for (auto u = it->begin(); u != it->end(); ++u) {
        if (!u->is_string()) throw InputError("'" + path.string() + "': units." + u.key() + ": expected a string");
        meta.units.emplace_back(u.key(), u->get<std::string>());
      }
    } else if (key == "frame_origin_m") {
      if (!it->is_array() || it->size() != 3) throw InputError("'" + path.string() + "': frame_origin_m: expected [x, y, z] in m");
      for (const auto& v : *it) {
        if (!v.is_number()) throw InputError("'" + path.string() + "': frame_origin_m: expected numbers");
        meta.frame_origin_m.push_back(v.get<double>());
      }
    } else if (key == "num_averages") {
      if (!it->is_array()) {
        throw InputError("'" + path.string() + "': num_averages: " + it->dump() +
                         ", expected an array of counts, one per input in the order the inputs first appear");
      }
      for (const auto& v : *it) {
        if (!v.is_number_integer() || v.get<long long>() < 2 || v.get<long long>() > 1000000000) {
          throw InputError("'" + path.string() + "': num_averages: " + v.dump() +
                           ", expected whole counts >= 2 (the hits averaged per input)");
        }
        meta.num_averages.push_back(v.get<int>());
      }
    } else if (key == "notes") {
      if (!it->is_array()) throw InputError("'" + path.string() + "': notes: expected an array of strings");
      for (const auto& v : *it) {
        if (v.is_string()) meta.notes.push_back(v.get<std::string>());
      }
    } else if (it->is_string()) {
      meta.fields[key] = it->get<std::string>();
    }
  }
  return meta;
}

}  // namespace stagefit
