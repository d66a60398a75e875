#!/usr/bin/env python3
"""Reference images from Mitsuba 3 for a scene written by
`radiosity export-mitsuba` (see src/mitsuba/export.rs for the translation).

Renders, each as two independent halves (seeds 1 and 2, spp/2 samples per
pixel each) so that the noise of their mean can be stated:
  le      scene.xml        max_depth 1          emission seen directly (Le)
  lights  lights_only.xml  max_depth 2          rho/pi * D (lights only)
  final   scene.xml        max_depth k+2 or -1  everything, k bounces
The run time's views are: direct = le + lights, final = final,
indirect = final - direct. Writes <out>/<name>_{a,b}.pfm (linear RGB,
PFM: little-endian, bottom row first) and <out>/meta.json (samples, depth,
variant, Mitsuba version, seconds, and the relative RMS noise of each view's
mean: |a - b| / 2 per pixel, over the RMS of the mean).
"""
import argparse
import json
import os
import struct
import sys
import time

import numpy as np
import mitsuba as mi


def write_pfm(path, img):
    h, w, _ = img.shape
    with open(path + ".tmp", "wb") as f:
        f.write(b"PF\n%d %d\n-1.0\n" % (w, h))
        f.write(np.ascontiguousarray(img[::-1, :, :3], dtype="<f4").tobytes())
    os.replace(path + ".tmp", path)


def rel_rms_noise(a, b):
    mean = 0.5 * (a + b)
    den = np.sqrt(np.mean(mean**2))
    return float(np.sqrt(np.mean((0.5 * (a - b)) ** 2)) / den) if den > 0 else 0.0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("export_dir")
    ap.add_argument("--out", required=True)
    ap.add_argument("--spp", type=int, default=256, help="samples per pixel, both halves together")
    ap.add_argument("--bounces", default="inf", help="k (1, 2, ...) or inf")
    ap.add_argument("--views", default="all", choices=["all", "direct"],
                    help="direct: only le and lights (no final, no indirect)")
    # llvm_ad_rgb aborts here inside LLVM (Mitsuba 3.9.1 wheels, this CPU):
    # scalar_rgb is the default.
    ap.add_argument("--variant", default="scalar_rgb")
    args = ap.parse_args()
    if args.spp < 2 or args.spp % 2:
        sys.exit(f"--spp {args.spp}: must be even and at least 2")
    if args.bounces == "inf":
        depth = -1
    else:
        try:
            k = int(args.bounces)
        except ValueError:
            sys.exit(f"--bounces {args.bounces!r}: expected a positive integer or inf")
        if k < 1:
            sys.exit(f"--bounces {k}: must be at least 1")
        depth = k + 2
    mi.set_variant(args.variant)
    os.makedirs(args.out, exist_ok=True)
    half = args.spp // 2
    jobs = [("le", "scene.xml", 1), ("lights", "lights_only.xml", 2)]
    if args.views == "all":
        jobs.append(("final", "scene.xml", depth))
    images, seconds = {}, {}
    for name, xml, d in jobs:
        t0 = time.time()
        scene = mi.load_file(os.path.join(args.export_dir, xml), max_depth=d)
        for tag, seed in (("a", 1), ("b", 2)):
            img = np.array(mi.render(scene, spp=half, seed=seed), dtype=np.float32)
            if not np.all(np.isfinite(img)):
                sys.exit(f"{name}_{tag}: Mitsuba returned non-finite pixels")
            images[name, tag] = img
            write_pfm(os.path.join(args.out, f"{name}_{tag}.pfm"), img)
        seconds[name] = time.time() - t0
        print(f"[mitsuba] {name}: max_depth {d}, {args.spp} spp, {seconds[name]:.1f} s", flush=True)
    view = {"direct": {t: images["le", t] + images["lights", t] for t in "ab"}}
    if args.views == "all":
        view["final"] = {t: images["final", t] for t in "ab"}
        view["indirect"] = {t: view["final"][t] - view["direct"][t] for t in "ab"}
    noise = {v: rel_rms_noise(x["a"], x["b"]) for v, x in view.items()}
    meta = {
        "mitsuba": mi.__version__,
        "variant": args.variant,
        "spp": args.spp,
        "bounces": args.bounces,
        "max_depth": depth if args.views == "all" else None,
        "views": args.views,
        "width": int(images["le", "a"].shape[1]),
        "height": int(images["le", "a"].shape[0]),
        "seconds": seconds,
        "noise_rel_rms": noise,
    }
    with open(os.path.join(args.out, "meta.json"), "w") as f:
        json.dump(meta, f, indent=2)
    print("[mitsuba] noise (relative RMS of the mean): " +
          ", ".join(f"{v} {100 * n:.2f} %" for v, n in noise.items()), flush=True)


if __name__ == "__main__":
    main()
