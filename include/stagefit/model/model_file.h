#pragma once
// Model files (TOML). The format is documented in docs/model-file.md; fitting/microstation.toml is the
// reference micro-station, also embedded in the program as the default model.

#include <filesystem>
#include <string>
#include <string_view>

#include "stagefit/model/model_spec.h"

namespace stagefit::model {

/// Parses a model from TOML text. Collects every problem (syntax, unknown keys, wrong types, units of
/// the wrong dimension, missing values, and everything ValidateModel() reports) and throws one
/// InputError listing them all, each as "<source>:<line>: <item>: <field> = <value>, expected ...".
ModelSpec ParseModelToml(std::string_view text, const std::string& source);

/// Reads and parses a model file. Throws InputError when the file cannot be read or is invalid.
ModelSpec ReadModelFile(const std::filesystem::path& path);

/// The model as TOML text. ParseModelToml(WriteModelToml(m)) reproduces m exactly (numbers are written
/// with 17 significant digits).
std::string WriteModelToml(const ModelSpec& spec);

/// Writes the model atomically; refuses to overwrite `protected_inputs`.
void WriteModelFile(const std::filesystem::path& path, const ModelSpec& spec);

/// The embedded reference micro-station (SPEC §2), parsed from the embedded copy of
/// fitting/microstation.toml.
ModelSpec DefaultModelSpec();
std::string_view DefaultModelToml();

/// `path` empty -> the default model; otherwise the file.
ModelSpec LoadModel(const std::string& path);

}  // namespace stagefit::model
