#pragma once
// Text read from files (channel names, column names) must be UTF-8 before it reaches a report (JSON)
// or another file; readers reject anything else as bad input.

#include <string>
#include <string_view>

namespace stagefit {

/// True when `text` is well-formed UTF-8 (RFC 3629: no overlong forms, no surrogates, code points up
/// to U+10FFFF).
bool IsValidUtf8(std::string_view text);

/// `text` for a message: well-formed UTF-8 kept, every other byte written as \xNN.
std::string EscapeNonUtf8(std::string_view text);

}  // namespace stagefit
