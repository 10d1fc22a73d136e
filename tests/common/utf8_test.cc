#include "stagefit/common/utf8.h"

#include <gtest/gtest.h>

namespace stagefit {
namespace {

TEST(IsValidUtf8, AcceptsAsciiAndWellFormedSequences) {
  EXPECT_TRUE(IsValidUtf8(""));
  EXPECT_TRUE(IsValidUtf8("hexapod.k.Rx"));
  EXPECT_TRUE(IsValidUtf8("m/s\xC2\xB2"));            // U+00B2
  EXPECT_TRUE(IsValidUtf8("\xE2\x82\xAC"));           // U+20AC
  EXPECT_TRUE(IsValidUtf8("\xF0\x9F\x98\x80"));       // U+1F600
  EXPECT_TRUE(IsValidUtf8("\xF4\x8F\xBF\xBF"));       // U+10FFFF, the last code point
}

TEST(IsValidUtf8, RejectsWhatJsonWritersReject) {
  EXPECT_FALSE(IsValidUtf8("a1\xFF"));                // never valid
  EXPECT_FALSE(IsValidUtf8("m/s\xB2"));               // Latin-1, a lone continuation byte
  EXPECT_FALSE(IsValidUtf8("\xC0\xAF"));              // overlong '/'
  EXPECT_FALSE(IsValidUtf8("\xE0\x80\xAF"));          // overlong, 3 bytes
  EXPECT_FALSE(IsValidUtf8("\xED\xA0\x80"));          // surrogate U+D800
  EXPECT_FALSE(IsValidUtf8("\xF4\x90\x80\x80"));      // above U+10FFFF
  EXPECT_FALSE(IsValidUtf8("\xE2\x82"));              // cut short
}

TEST(EscapeNonUtf8, KeepsValidTextAndEscapesTheRest) {
  EXPECT_EQ(EscapeNonUtf8("a1x"), "a1x");
  EXPECT_EQ(EscapeNonUtf8("m/s\xC2\xB2"), "m/s\xC2\xB2");
  EXPECT_EQ(EscapeNonUtf8("a1\xFF\xFE"), "a1\\xFF\\xFE");
  EXPECT_EQ(EscapeNonUtf8("\xE2\x82x"), "\\xE2\\x82x");
}

}  // namespace
}  // namespace stagefit
