// libFuzzer target over the deck reader (`rkfem check` up to the model build): any bytes as a
// deck. The reader must return a deck or throw DeckError, whose message is one line; nothing
// else (another exception, a crash, a hang, an ASan or UBSan report) is allowed. A deck it
// accepts must print as the resolved deck (to_yaml, what `check` prints), and that print must
// read back. Inputs whose first line is `#set key=value` also apply that override, so the
// `--set` path is fuzzed with the rest. Inputs that start with '*' are LS-DYNA keyword decks: they
// go through the importer (config/keyword_deck.hpp), whose deck must then read, or whose error
// must be one line.
// Build and run: scripts/fuzz-smoke (CI: a few thousand inputs), scripts/fuzz-smoke SECONDS.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <unistd.h>
#include <vector>

#include "rkfem/config/deck.hpp"
#include "rkfem/config/keyword_deck.hpp"
#include "rkfem/core/error.hpp"

namespace
{
[[noreturn]] void fail(const char* what, const std::string& detail)
{
    std::fprintf(stderr, "deck_fuzz: %s\n%s\n", what, detail.c_str());
    std::abort();
}

void check_message(const std::string& m)
{
    if (m.empty())
        fail("an empty error message", m);
    for (const char c : m)
        if (c == '\n' || c == '\0')
            fail("an error message that is not one line", m);
}
} // namespace

/// A keyword deck: imported (from a file, as the driver reads it), then read as a deck.
int keyword_input(const std::string& text)
{
    static const std::string path = "/tmp/rkfem_deck_fuzz_" + std::to_string(getpid()) + ".k";
    if (FILE* f = std::fopen(path.c_str(), "wb"))
    {
        std::fwrite(text.data(), 1, text.size(), f);
        std::fclose(f);
    }
    try
    {
        const rkfem::KeywordImport im =
            rkfem::import_keyword_deck(path, rkfem::keyword_units("mm-ms-kg-kN"), text.size() % 2 == 0, path);
        (void)rkfem::parse_deck(im.yaml, path + " (imported)");
    }
    catch (const rkfem::DeckError& e)
    {
        check_message(e.what());
    }
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    const std::string text(reinterpret_cast<const char*>(data), size);
    if (!text.empty() && text[0] == '*')
        return keyword_input(text);
    std::vector<std::string> overrides;
    if (text.rfind("#set ", 0) == 0)
        overrides.push_back(
            text.substr(5, text.find('\n') == std::string::npos ? std::string::npos : text.find('\n') - 5));
    std::string echo;
    try
    {
        const rkfem::Deck deck = rkfem::parse_deck(text, "fuzz.yaml", overrides);
        echo = rkfem::to_yaml(deck);
    }
    catch (const rkfem::DeckError& e)
    {
        check_message(e.what());
        return 0;
    }
    try
    {
        (void)rkfem::parse_deck(echo, "echo.yaml");
    }
    catch (const rkfem::DeckError& e)
    {
        fail("the resolved deck of an accepted deck does not read back", std::string(e.what()) + "\n" + echo);
    }
    return 0;
}
