#!/usr/bin/env python3
"""Irradiance at points from Mitsuba 3's irradiance meter, for a scene
written by `radiosity export-mitsuba` (src/mitsuba/export.rs), as
`radiosity bench probes` compares the probes with (docs/probes.md).

Reads a JSON list of {"position": [x, y, z], "normal": [x, y, z]} and, for
each, measures with an `irradiancemeter` on a square of side `--size`
centred at the point and facing the normal (the square is not part of the
scene: it occludes nothing). Rays leave the square cosine-distributed, so
the meter sees surfaces, area emitters and the environment, and not the
delta lights (point, spot, directional), whose direct light the run time
adds apart: the quantity the probes hold. Two independent halves (seeds 1
and 2) give each value's noise. Writes a JSON list of
{"a": [r, g, b], "b": [r, g, b]}.
"""
import argparse
import json
import sys

import numpy as np
import mitsuba as mi


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("export_dir")
    ap.add_argument("points")
    ap.add_argument("--out", required=True)
    ap.add_argument("--spp", type=int, default=4096, help="paths per point, both halves together")
    ap.add_argument("--size", type=float, required=True, help="the meter square's side, scene units")
    ap.add_argument("--variant", default="scalar_rgb")
    args = ap.parse_args()
    if args.spp < 2 or args.spp % 2:
        sys.exit(f"--spp {args.spp}: must be even and at least 2")
    mi.set_variant(args.variant)
    scene = mi.load_file(args.export_dir + "/scene.xml", max_depth=-1)
    points = json.load(open(args.points))
    T = mi.ScalarTransform4f
    out = []
    for k, p in enumerate(points):
        x = mi.ScalarPoint3f(*p["position"])
        n = np.array(p["normal"], dtype=float)
        up = [0.0, 1.0, 0.0] if abs(n[1]) < 0.9 else [1.0, 0.0, 0.0]
        to_world = T().look_at(origin=x, target=x + mi.ScalarVector3f(*n), up=up) @ T().scale(0.5 * args.size)
        shape = mi.load_dict({
            "type": "rectangle",
            "to_world": to_world,
            "sensor": {
                "type": "irradiancemeter",
                "film": {"type": "hdrfilm", "width": 1, "height": 1,
                         "rfilter": {"type": "box"}, "pixel_format": "rgb"},
                "sampler": {"type": "independent", "sample_count": args.spp // 2},
            },
        })
        sensor = shape.sensor()
        halves = []
        for seed in (1, 2):
            img = np.array(mi.render(scene, sensor=sensor, spp=args.spp // 2, seed=seed + 2 * k),
                           dtype=np.float64)
            v = img.reshape(-1)[:3]
            if not np.all(np.isfinite(v)):
                sys.exit(f"point {k}: Mitsuba returned a non-finite irradiance")
            halves.append([float(c) for c in v])
        out.append({"a": halves[0], "b": halves[1]})
    json.dump(out, open(args.out, "w"))


if __name__ == "__main__":
    main()
