// Replays stored inputs through one libFuzzer program's LLVMFuzzerTestOneInput without libFuzzer: the
// seeds of corpus/<program>/ and the inputs that once crashed a reader, regressions/<program>/. Built
// by the normal test build (stagefit_fuzzer() of cmake/StagefitHelpers.cmake) and run by CTest, so that every build with tests,
// the sanitizer build included, keeps those inputs passing; exploring for new ones is scripts/fuzz.sh.
//
// Usage: <program>_replay FILE_OR_FOLDER...   (folders: every regular file below them, in name order)
// Exit 0 when every input ends normally or with an InputError; 1, naming the input and the exception,
// when one throws anything else; 2 when an argument cannot be read.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size);

int main(int argc, char** argv) {
  namespace fs = std::filesystem;
  std::vector<fs::path> inputs;
  for (int i = 1; i < argc; ++i) {
    const fs::path arg = argv[i];
    std::error_code ec;
    if (fs::is_directory(arg, ec)) {
      for (const auto& entry : fs::recursive_directory_iterator(arg)) {
        if (entry.is_regular_file()) inputs.push_back(entry.path());
      }
    } else if (fs::is_regular_file(arg, ec)) {
      inputs.push_back(arg);
    } else {
      std::fprintf(stderr, "replay: %s: not a file or folder\n", arg.c_str());
      return 2;
    }
  }
  std::sort(inputs.begin(), inputs.end());
  for (const fs::path& path : inputs) {
    std::ifstream in(path, std::ios::binary);
    if (!in) {
      std::fprintf(stderr, "replay: %s: cannot be opened\n", path.c_str());
      return 2;
    }
    const std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    try {
      LLVMFuzzerTestOneInput(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
    } catch (const std::exception& e) {
      std::fprintf(stderr, "replay: %s: threw %s\n", path.c_str(), e.what());
      return 1;
    }
  }
  std::printf("replay: %zu inputs, none threw anything but InputError\n", inputs.size());
  return 0;
}
