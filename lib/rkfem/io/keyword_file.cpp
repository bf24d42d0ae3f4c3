#include "rkfem/io/keyword_file.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "rkfem/core/input_error.hpp"

namespace rkfem
{
namespace
{
std::string trim(const std::string& s)
{
    const auto a = s.find_first_not_of(" \t\r");
    if (a == std::string::npos)
        return "";
    const auto b = s.find_last_not_of(" \t\r");
    return s.substr(a, b - a + 1);
}

std::string upper(std::string s)
{
    std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::toupper(c); });
    return s;
}

/// Reads `path`'s blocks into `out`, following *INCLUDE; `open` holds the files being read (a cycle's check),
/// `files` gets every file read, in reading order. Errors are the caller's (`at`: the deck key or file that
/// asked for the file).
void read_file(const std::string& path, const std::string& included_at, const SourceLocation& at,
               std::vector<std::string>& open, std::vector<std::string>& files, std::vector<KeywordBlock>& out)
{
    std::error_code ec;
    const std::string canonical = std::filesystem::weakly_canonical(path, ec).string();
    if (std::find(open.begin(), open.end(), canonical) != open.end())
        throw DeckError(
            at, included_at + ": *INCLUDE " + path + " includes a file that is already being read (an include cycle)",
            "expected each file included once along a chain");
    std::ifstream in(path);
    if (!in)
        throw DeckError(at, (included_at.empty() ? std::string() : included_at + ": ") + path + " cannot be opened",
                        "expected a readable LS-DYNA keyword file");
    open.push_back(canonical);
    files.push_back(path);
    std::string text;
    int line = 0;
    bool in_include = false; // the last keyword was *INCLUDE and its file name is next
    int include_line = 0;
    while (std::getline(in, text))
    {
        ++line;
        if (!text.empty() && text.back() == '\r')
            text.pop_back();
        if (!text.empty() && text[0] == '$')
            continue;
        if (text[0] == '*')
        {
            if (in_include)
                throw DeckError(at, path + ":" + std::to_string(include_line) + ": *INCLUDE names no file",
                                "expected the file's name on the next card");
            // the keyword is the line's first word ("*ELEMENT_SOLID (ten nodes format)", "*KEYWORD 100m")
            std::string kw = upper(trim(text));
            kw = kw.substr(0, kw.find_first_of(" \t"));
            if (kw == "*END")
                break;
            if (kw == "*INCLUDE")
            {
                in_include = true;
                include_line = line;
                continue;
            }
            out.push_back({kw, path, line, {}});
            continue;
        }
        if (trim(text).empty())
        {
            // a blank card is a card (all its fields default: a part's empty heading, a contact's
            // default second card); before any keyword, or where a file name is due, it is nothing
            if (!out.empty() && !in_include)
                out.back().cards.push_back({"", line});
            continue;
        }
        if (in_include)
        {
            in_include = false;
            std::filesystem::path inc(trim(text));
            if (inc.is_relative())
                inc = std::filesystem::path(path).parent_path() / inc;
            read_file(inc.string(), path + ":" + std::to_string(line), at, open, files, out);
            // cards after an include's file belong to no block until the next keyword
            out.push_back({"*INCLUDE", path, line, {}});
            continue;
        }
        if (out.empty())
            out.push_back({"", path, line, {}}); // cards before any keyword: refused by the readers
        out.back().cards.push_back({text, line});
    }
    if (in_include)
        throw DeckError(at, path + ":" + std::to_string(include_line) + ": *INCLUDE names no file",
                        "expected the file's name on the next card");
    open.pop_back();
}
} // namespace

std::string KeywordBlock::where(int i) const
{
    const int l = i >= 0 && i < static_cast<int>(cards.size()) ? cards[static_cast<std::size_t>(i)].line : line;
    return file + ":" + std::to_string(l);
}

std::vector<KeywordBlock> read_keyword_blocks(const std::string& path, const SourceLocation& at,
                                              std::vector<std::string>* files)
{
    std::vector<KeywordBlock> out;
    std::vector<std::string> open, read;
    read_file(path, "", at, open, read, out);
    if (files)
        *files = std::move(read);
    // the markers after includes, holding no card or only blank ones, are dropped
    out.erase(std::remove_if(out.begin(), out.end(),
                             [](const KeywordBlock& b)
                             {
                                 return b.keyword == "*INCLUDE" &&
                                        std::all_of(b.cards.begin(), b.cards.end(),
                                                    [](const KeywordCard& c) { return c.blank(); });
                             }),
              out.end());
    return out;
}

std::vector<std::string> keyword_fields(const std::string& line, const std::vector<int>& widths)
{
    std::vector<std::string> out;
    if (line.find(',') != std::string::npos)
    {
        std::size_t a = 0;
        for (;;)
        {
            const std::size_t b = line.find(',', a);
            out.push_back(trim(line.substr(a, b == std::string::npos ? std::string::npos : b - a)));
            if (b == std::string::npos)
                break;
            a = b + 1;
        }
        return out;
    }
    std::size_t at = 0;
    for (int w : widths)
    {
        if (at >= line.size())
            break;
        out.push_back(trim(line.substr(at, static_cast<std::size_t>(w))));
        at += static_cast<std::size_t>(w);
    }
    return out;
}

bool keyword_number(const std::string& field, double fallback, double& value)
{
    if (field.empty())
    {
        value = fallback;
        return true;
    }
    std::string f = field;
    for (char& c : f)
        if (c == 'd' || c == 'D')
            c = 'e';
    // Fortran's exponent without its letter: a sign after a digit or point, not at the start
    for (std::size_t k = 1; k < f.size(); ++k)
        if ((f[k] == '-' || f[k] == '+') && (std::isdigit(static_cast<unsigned char>(f[k - 1])) || f[k - 1] == '.'))
        {
            f.insert(k, 1, 'e');
            break;
        }
    std::size_t used = 0;
    try
    {
        value = std::stod(f, &used);
    }
    catch (const std::exception&)
    {
        return false;
    }
    return used == f.size() && std::isfinite(value);
}
} // namespace rkfem
