#pragma once
// Checks the element tree of a MATLAB .mat file before matio reads it (used by mat_file.cc and
// raw_hammer_file.cc). matio allocates by the sizes a file declares (dimensions, names,
// cell counts) before it reads them, so a damaged size field would exhaust memory inside matio.
// File names in the messages, v5 variables by number (1 = first), v7.3 objects by HDF5 path.

#include <cstdint>
#include <filesystem>

namespace stagefit::measurement::internal {

/// Largest number of dimensions and nesting depth (cells) accepted in a .mat file.
inline constexpr int kMaxMatRank = 32;
inline constexpr int kMaxMatNesting = 32;

/// Throws InputError naming the file, the variable (v5: by number, 1 = first; v7.3: by HDF5 path)
/// and the problem, unless `path` is
///  - a v5 file whose every element fits in the bytes that follow it: top-level variables, array
///    flags (a full miUINT32 element of 8 bytes), dimensions (a full miINT32 element of at most
///    kMaxMatRank dimensions, each at most `max_inflated_bytes`, and so their product for char
///    arrays and arrays inside cells), names (miINT8), data (a non-empty char or numeric array's
///    first data element inside the array), cells (nested at most kMaxMatNesting deep), inside
///    compressed variables too, which must inflate without error to at most `max_inflated_bytes`
///    each; laid out as matio reads it, so that matio reads every size from where this check did;
///    and of the array classes a reader takes only: numeric, char and cell arrays (matio allocates
///    by sizes inside sparse matrices and leaks what it reads of a function handle);
///  - or a v7.3 (HDF5) file whose every dataset and attribute holds at most `max_inflated_bytes`
///    in at most kMaxMatRank dimensions (a file HDF5 cannot open is left to matio to report).
/// Files without a v5 or v7.3 header (v4 and others) are rejected: stagefit reads v5 and v7.3 only.
/// The v5 check reads the file once and never allocates by a declared size.
void CheckMatFileStructure(const std::filesystem::path& path, std::uint64_t max_inflated_bytes);

}  // namespace stagefit::measurement::internal
