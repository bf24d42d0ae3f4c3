#pragma once
/// @file json_text.hpp
/// A string as a JSON string literal: what summary.json and the deck schema (rkfem schema) write.
#include <cstdio>
#include <string>
#include <string_view>

namespace rkfem
{
/// s quoted, with " and \ escaped, newlines and tabs as \n and \t, other control characters as \u00XX.
inline std::string json_quote(std::string_view s)
{
    std::string out = "\"";
    for (const char c : s)
        switch (c)
        {
        case '"':
            out += "\\\"";
            break;
        case '\\':
            out += "\\\\";
            break;
        case '\n':
            out += "\\n";
            break;
        case '\t':
            out += "\\t";
            break;
        default:
            if (static_cast<unsigned char>(c) < 0x20)
            {
                char b[8];
                std::snprintf(b, sizeof b, "\\u%04x", static_cast<unsigned>(static_cast<unsigned char>(c)));
                out += b;
            }
            else
                out += c;
        }
    return out + "\"";
}
} // namespace rkfem
