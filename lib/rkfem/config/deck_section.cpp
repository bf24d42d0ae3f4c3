#include "rkfem/config/deck_section.hpp"

namespace rkfem::deck_detail
{
std::size_t edit_distance(std::string_view a, std::string_view b)
{
    std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
    for (std::size_t j = 0; j <= b.size(); ++j)
        prev[j] = j;
    for (std::size_t i = 1; i <= a.size(); ++i)
    {
        cur[0] = i;
        for (std::size_t j = 1; j <= b.size(); ++j)
            cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] == b[j - 1] ? 0u : 1u)});
        std::swap(prev, cur);
    }
    return prev[b.size()];
}

SourceLocation locate(const Context& ctx, const YAML::Node& node, const std::string& path)
{
    for (const auto& [p, text] : ctx.overridden)
        if (path == p || path.rfind(p + ".", 0) == 0)
            return {"--set " + text, path};
    const YAML::Mark m = node.Mark();
    if (m.is_null() || m.line < 0)
    {
        // a node without a place in the file was made by a --set below it (--set a.x.y=1 makes a.x)
        for (const auto& [p, text] : ctx.overridden)
            if (p.rfind(path + ".", 0) == 0)
                return {"--set " + text, path};
        return {ctx.name, path};
    }
    return {ctx.name + ":" + std::to_string(m.line + 1), path};
}
} // namespace rkfem::deck_detail
