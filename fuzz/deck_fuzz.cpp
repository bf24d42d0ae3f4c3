// libFuzzer target over the deck reader (`rkfem check` up to the model build): any bytes as a
// deck. The reader must return a deck or throw DeckError, whose message is one line; nothing
// else (another exception, a crash, a hang, an ASan or UBSan report) is allowed. A deck it
// accepts must print as the resolved deck (to_yaml, what `check` prints), and that print must
// read back. Inputs whose first line is `#set key=value` also apply that override, so the
// `--set` path is fuzzed with the rest.
// Build and run: scripts/fuzz-smoke (CI: a few thousand inputs), scripts/fuzz-smoke SECONDS.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "rkfem/config/deck.hpp"
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

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    const std::string text(reinterpret_cast<const char*>(data), size);
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
