// Messages of InputError (forward/common/error.hpp): one line, bounded, valid UTF-8.

#include "forward/common/error.hpp"

#include <gtest/gtest.h>

#include <string>

using namespace diffipc;

namespace {
/// Independent check: every byte sequence decodes as UTF-8 by the standard's table
/// (RFC 3629: no overlong forms, no surrogates, at most U+10FFFF).
bool valid_utf8(const std::string& s)
{
    for (size_t i = 0; i < s.size();) {
        const unsigned char c = static_cast<unsigned char>(s[i]);
        size_t n = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xe ? 3 : (c >> 3) == 0x1e ? 4 : 0;
        if (n == 0 || i + n > s.size())
            return false;
        unsigned long code = n == 1 ? c : c & (0xff >> (n + 1));
        for (size_t k = 1; k < n; ++k) {
            const unsigned char d = static_cast<unsigned char>(s[i + k]);
            if ((d & 0xc0) != 0x80)
                return false;
            code = (code << 6) | (d & 0x3f);
        }
        const unsigned long smallest[5] = { 0, 0, 0x80, 0x800, 0x10000 };
        if (code < smallest[n] || code > 0x10ffff || (code >= 0xd800 && code <= 0xdfff))
            return false;
        i += n;
    }
    return true;
}
} // namespace

TEST(ErrorMessage, BytesThatAreNotUtf8BecomeQuestionMarks)
{
    // Before: an invalid byte of a malformed file reached the message as it was, and Python
    // raised a ValueError with an empty message (the text could not become a str).
    const InputError e("problem.json", std::string("last read: '0\xc3'; expected '}'"));
    EXPECT_STREQ(e.what(), "problem.json: last read: '0?'; expected '}'");
    EXPECT_TRUE(valid_utf8(e.what()));
}

TEST(ErrorMessage, ValidUtf8IsKept)
{
    const std::string text = "caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80";
    EXPECT_EQ(clip_message(text), text);
}

TEST(ErrorMessage, EveryInvalidFormIsReplaced)
{
    // Stray continuation, truncated sequences, overlong forms, surrogates, beyond U+10FFFF.
    for (const std::string bad : { "\x80", "\xc3", "\xe2\x82", "\xc0\xaf", "\xe0\x80\xaf", "\xed\xa0\x80",
             "\xf4\x90\x80\x80", "\xf5\x80\x80\x80", "\xff" }) {
        const std::string shown = clip_message("a" + bad + "b");
        EXPECT_TRUE(valid_utf8(shown)) << shown;
        EXPECT_EQ(shown.front(), 'a');
        EXPECT_EQ(shown.back(), 'b');
        EXPECT_NE(shown.find('?'), std::string::npos) << shown;
    }
}

TEST(ErrorMessage, ALongMessageIsNotCutInsideACharacter)
{
    std::string text(MAX_ERROR_MESSAGE - 1, 'x');
    for (int i = 0; i < 50; ++i)
        text += "\xe2\x82\xac";
    const std::string shown = clip_message(text);
    EXPECT_TRUE(valid_utf8(shown)) << shown.substr(MAX_ERROR_MESSAGE - 4, 8);
    EXPECT_NE(shown.find("more characters"), std::string::npos);
    EXPECT_LE(shown.size(), MAX_ERROR_MESSAGE + 40);
}

TEST(ErrorMessage, ControlCharactersAndNulAreShown)
{
    EXPECT_EQ(clip_message(std::string("a\nb\0c\x01", 6)), "a b\\0c?");
}
