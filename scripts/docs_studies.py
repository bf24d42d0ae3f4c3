#!/usr/bin/env python3
"""The seed problems as the suite measured them: each study the test run left under
build/release/verification (its table.md, ours beside the published values) and the figures its
notebooks drew there, as one Markdown page. The figures are copied beside the page.
Usage: docs_studies.py VERIFICATION_DIR PAGE_DIR > page.md"""
import os
import shutil
import sys


def main():
    root, page_dir = sys.argv[1], sys.argv[2]
    print("# Seed problems, as measured\n")
    def is_study(d):
        path = os.path.join(root, d)
        return os.path.isdir(path) and (os.path.isfile(os.path.join(path, "table.md")) or
                                        any(f.endswith(".png") for f in os.listdir(path)))

    studies = sorted(d for d in (os.listdir(root) if os.path.isdir(root) else []) if is_study(d))
    if not studies:
        print(f"No study output under `{root}`: run `ctest --preset release` first, then this page's script.")
        return
    print(f"The smoke cases of the study files that `ctest --preset release` ran, read from `{root}`: "
          "each table puts ours beside the published value with the relative difference; the study "
          "files and their tests say which bands hold. The full studies (long label) are in "
          "[Seed problems](seed-problems.md).\n")
    figures = os.path.join(page_dir, "measured")
    os.makedirs(figures, exist_ok=True)
    for d in studies:
        path = os.path.join(root, d)
        print(f"## {d}\n")
        table = os.path.join(path, "table.md")
        if os.path.isfile(table):
            for line in open(table, encoding="utf-8", errors="replace").read().splitlines():
                # the table's own title becomes a paragraph: the section heading is the study's
                print(line[2:] if line.startswith("# ") else ("#" + line if line.startswith("## ") else line))
            print()
        for f in sorted(x for x in os.listdir(path) if x.endswith(".png")):
            shutil.copy(os.path.join(path, f), os.path.join(figures, f"{d}_{f}"))
            print(f"![{d}: {f}](measured/{d}_{f})\n")


if __name__ == "__main__":
    main()
