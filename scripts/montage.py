#!/usr/bin/env python3
"""Lay PNG pictures side by side (rows of --cols), with an optional caption strip under each.

    scripts/montage.py A.png B.png ... -o STRIP.png [--cols 4] [--labels "a|b|..."] [--gap 4]

Used by scripts/paper_figures.sh for the paper's figures as frame sequences. Pictures of
different sizes are scaled to the first one's height.
"""
import argparse
import sys

from PIL import Image, ImageDraw, ImageFont


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("pictures", nargs="+")
    p.add_argument("-o", "--output", required=True)
    p.add_argument("--cols", type=int, default=0, help="pictures per row (default: all)")
    p.add_argument("--labels", default="", help="one caption per picture, '|'-separated")
    p.add_argument("--gap", type=int, default=4, help="pixels between pictures")
    a = p.parse_args()
    try:
        images = [Image.open(f).convert("RGB") for f in a.pictures]
    except OSError as e:
        sys.exit(f"montage: {e}")
    h = images[0].height
    images = [im if im.height == h else im.resize((im.width * h // im.height, h)) for im in images]
    labels = a.labels.split("|") if a.labels else []
    if labels and len(labels) != len(images):
        sys.exit(f"montage: {len(labels)} labels for {len(images)} pictures")
    cols = a.cols or len(images)
    rows = (len(images) + cols - 1) // cols
    w = max(im.width for im in images)
    cap = 28 if labels else 0
    out = Image.new("RGB", (cols * w + (cols - 1) * a.gap, rows * (h + cap) + (rows - 1) * a.gap),
                    "white")
    draw = ImageDraw.Draw(out)
    try:
        font = ImageFont.truetype("DejaVuSans.ttf", 18)
    except OSError:
        font = ImageFont.load_default()
    for i, im in enumerate(images):
        x, y = (i % cols) * (w + a.gap), (i // cols) * (h + cap + a.gap)
        out.paste(im, (x, y))
        if labels:
            draw.text((x + 6, y + h + 4), labels[i], fill="black", font=font)
    out.save(a.output)
    print(f"montage: {a.output} ({out.width}x{out.height}, {len(images)} pictures)")


if __name__ == "__main__":
    main()
