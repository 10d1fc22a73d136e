#include "state_space_export.h"

#include "stagefit/common/error.h"

namespace stagefit::cli {

std::vector<std::string> WriteStateSpaceMat(const std::string& out, const model::StateSpace&,
                                            const model::SecondOrderSystem&) {
  throw UsageError("export to .mat ('" + out + "') is not available in this build; use a .csv stem");
}

}  // namespace stagefit::cli
