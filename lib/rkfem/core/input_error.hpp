#pragma once
/// @file input_error.hpp
/// Where an input value came from and the one error type for bad input: a deck key, a --set
/// override or a line of a mesh file. Every layer that checks input throws DeckError.
#include <stdexcept>
#include <string>

namespace rkfem
{
/// Where a value came from: "deck.yaml:12" or "--set parts.a.E=1".
struct SourceLocation
{
    std::string where; ///< "FILE:LINE" or "--set ..."
    std::string path;  ///< key path, e.g. "parts.column.material.nu"
};

/// Thrown for any bad input. what() is one line: "DECK:LINE: key.path: what is wrong; expected".
class DeckError : public std::runtime_error
{
  public:
    DeckError(const SourceLocation& loc, const std::string& problem, const std::string& expected);
    const SourceLocation location;
};
} // namespace rkfem
