#pragma once
/// @file keyword_file.hpp
/// LS-DYNA keyword files as blocks of cards: what the keyword mesh reader
/// (discretization/keyword_mesh.hpp) and the deck importer (config/keyword_deck.hpp) read.
///
/// A block starts at a line whose first character is '*' (the keyword: the line's first word,
/// upper-cased, options and all: `*CONTACT_AUTOMATIC_SURFACE_TO_SURFACE_ID`; what follows it on
/// the line, "*KEYWORD 100m" or "*ELEMENT_SOLID (ten nodes format)", is not read) and holds the
/// lines up to the next keyword.
/// Lines starting with '$' are comments; a blank line inside a block is a card whose fields all
/// default (LS-DYNA reads it so: an empty part heading, a default contact card), and readers of
/// repeated rows skip it; `*END` ends a file.
/// `*INCLUDE` is followed where it stands: its next card names a file, relative to the folder of
/// the file that includes it (LS-DYNA's default search), read in place; a file that includes
/// itself, directly or not, is an error. Every card remembers its file and line.
#include <string>
#include <vector>

#include "rkfem/core/input_error.hpp"

namespace rkfem
{
struct KeywordCard
{
    std::string text; ///< the line, without its line end
    int line = 0;     ///< 1-based line in `file`
    bool blank() const { return text.find_first_not_of(" \t\r") == std::string::npos; }
};

struct KeywordBlock
{
    std::string keyword; ///< upper-case, trimmed, e.g. "*SET_NODE_LIST_TITLE"
    std::string file;    ///< the file the block is in (as opened)
    int line = 0;        ///< the keyword's line
    std::vector<KeywordCard> cards;
    /// "FILE:LINE" of card i (the keyword's own line for i < 0 or past the end)
    std::string where(int i = -1) const;
};

/// Every block of `path` and the files it includes, in reading order; with `files`, the files
/// read (`path` first, then each include as it is reached, as opened). Throws DeckError at `at`
/// (the deck key or file that names `path`), naming the file and line, for a file that cannot be
/// opened, an *INCLUDE without a file name, or an include cycle.
std::vector<KeywordBlock> read_keyword_blocks(const std::string& path, const SourceLocation& at,
                                              std::vector<std::string>* files = nullptr);

/// The fields of a card: comma-separated (free format) or fixed columns of the given widths
/// (LS-DYNA's standard format: 10 columns per field on most keywords, 8/16 on *NODE and
/// *ELEMENT_SOLID), each trimmed; a short line gives fewer fields.
std::vector<std::string> keyword_fields(const std::string& line, const std::vector<int>& widths);

/// A keyword number field: blank is `fallback`; Fortran exponents (1.0d-3, 1.0-3, 2.1+5) are
/// read as LS-DYNA reads them. False when the text is no number.
bool keyword_number(const std::string& field, double fallback, double& value);
} // namespace rkfem
