// Builds a model from a deck through the installed headers and library, and checks the counts a
// 2 x 2 x 20 mm column of 1 mm hexes has: 3 x 3 x 21 = 189 nodes and 80 elements.
#include <cstdio>

#include "rkfem/config/deck.hpp"
#include "rkfem/model/model.hpp"

int main(int argc, char** argv)
{
    if (argc != 2)
        return 2;
    const rkfem::Deck deck = rkfem::read_deck(argv[1], {"parts.column.generator.size=[2 mm, 2 mm, 20 mm]"});
    const rkfem::Model model = rkfem::Model::build(deck);
    std::printf("installed rkfem: %lld nodes, %lld elements\n", static_cast<long long>(model.nodes.size()),
                static_cast<long long>(model.n_elements()));
    return model.nodes.size() == 189 && model.n_elements() == 80 ? 0 : 1;
}
