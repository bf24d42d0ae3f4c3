# Sphinx configuration of the rkfem manual (scripts/docs builds it to build/docs/html; CI builds it
# with warnings as errors). Pages are Markdown, read by MyST (Debian's python3-myst-parser).
project = "rkfem"
author = "the rkfem developers"
extensions = ["myst_parser"]
source_suffix = {".md": "markdown"}
exclude_patterns = ["_build"]
myst_heading_anchors = 3
html_theme = "alabaster"
html_theme_options = {"page_width": "1100px", "sidebar_width": "260px"}
html_show_sourcelink = False
# Theory pages write equations as $...$ and $$...$$ (MyST's dollarmath; amsmath for aligned blocks).
myst_enable_extensions = ["dollarmath", "amsmath"]
