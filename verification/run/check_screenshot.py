"""Checks a screenshot of a run (scripts/screenshot): a PNG of the requested size in which the
part is drawn, coloured by its field: at least 1 % of the pixels differ from the background (the
most common colour) and they take at least 20 distinct colours.

Usage: python3 verification/run/check_screenshot.py PNG WIDTH HEIGHT
"""
import sys

import matplotlib.image as mpimg
import numpy as np


def main(path, width, height):
    img = mpimg.imread(path)
    if img.shape[0] != height or img.shape[1] != width:
        sys.exit(f"{path}: {img.shape[1]} x {img.shape[0]} pixels, expected {width} x {height}")
    rgb = (np.asarray(img)[:, :, :3] * 255).round().astype(np.int64)
    codes = (rgb[:, :, 0] << 16) | (rgb[:, :, 1] << 8) | rgb[:, :, 2]
    values, counts = np.unique(codes, return_counts=True)
    background = values[counts.argmax()]
    drawn = codes != background
    colours = len(np.unique(codes[drawn]))
    share = drawn.mean()
    print(f"{path}: {width} x {height}, {100 * share:.1f} % drawn, {colours} colours")
    if share < 0.01 or colours < 20:
        sys.exit(f"{path}: the part is not drawn in colour ({100 * share:.2f} % of the pixels, {colours} colours)")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]))
