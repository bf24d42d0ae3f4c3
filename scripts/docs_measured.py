#!/usr/bin/env python3
"""The verification manual's measured figures: every line each test printed in the last ctest
run (ctest's LastTest.log), by test, GoogleTest's own lines left out. Writes Markdown to stdout."""
import re
import sys

BOILERPLATE = re.compile(r"^(\[[ =A-Z-]+\]|Running main\(\)|Note: Google Test filter|$)")


def tests(text):
    """(name, output lines, passed) for each test of the log."""
    starts = list(re.finditer(r"^\d+/\d+ Testing: (\S+)$", text, re.M))
    for k, m in enumerate(starts):
        block = text[m.start():starts[k + 1].start() if k + 1 < len(starts) else len(text)]
        name = m.group(1)
        out = re.search(r"Output:\n-+\n(.*?)<end of output>", block, re.S)
        lines = [l.rstrip() for l in (out.group(1).splitlines() if out else [])]
        passed = "Test Passed." in block
        yield name, [l for l in lines if not BOILERPLATE.match(l)], passed


def main():
    path = sys.argv[1] if len(sys.argv) > 1 else "build/release/Testing/Temporary/LastTest.log"
    print("# Measured, by test\n")
    try:
        text = open(path, encoding="utf-8", errors="replace").read()
    except OSError:
        print(f"No test log at `{path}`: run `ctest --preset release` first, then `scripts/docs`.")
        return
    started = re.search(r"Start testing: (.*)", text)
    found = sorted(tests(text))
    print(f"From `{path}`" + (f", the run started {started.group(1).strip()}" if started else "") +
          f": {len(found)} tests, {sum(1 for _, _, p in found if p)} passed.\n")
    for name, lines, passed in found:
        print(f"## {name}\n")
        print("Passed." if passed else "**Did not pass.**")
        print()
        if lines:
            print("```text")
            for l in lines:
                print(l.replace("```", "'''"))
            print("```")
        else:
            print("(printed nothing beyond GoogleTest's own lines)")
        print()


if __name__ == "__main__":
    main()
