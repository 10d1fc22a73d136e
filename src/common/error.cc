#include "stagefit/common/error.h"

namespace stagefit::internal {

void AssertionFailed(const char* condition, const char* file, int line, const std::string& message) {
  std::ostringstream out;
  out << "internal error: " << condition << " failed at " << file << ":" << line;
  if (!message.empty()) out << ": " << message;
  throw std::logic_error(out.str());
}

}  // namespace stagefit::internal
