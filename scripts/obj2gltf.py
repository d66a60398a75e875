#!/usr/bin/env python3
"""Converts an OBJ scene with its MTL materials to glTF 2.0, independently of
the project's Rust code (standard library only), so that the glTF loader can
be checked against the OBJ loader on the same scene.

    scripts/obj2gltf.py scene.obj out.glb     # one binary file, images inside
    scripts/obj2gltf.py scene.obj out.gltf    # JSON + out.bin, images by URI

What it writes (glTF 2.0 spec sections in brackets):
- one mesh on one node, one triangle primitive per run of faces with the
  same material, in the file's order [3.7.2]; polygons are fanned from
  their first vertex; each primitive has its own vertices (every distinct
  v/vt/vn triple), POSITION with min/max, NORMAL and TEXCOORD_0 where every
  face of the run has them [3.7.2.1];
- texture coordinates with v flipped (OBJ has v up, glTF v down) [3.7.2.1];
- a material per MTL material, in the MTL's order: baseColorFactor = Kd
  (1 with map_Kd and no Kd, 0.8 with neither), metallic 0, roughness 1,
  baseColorTexture = map_Kd (repeat sampler); emissiveFactor = Ke / pi (glTF
  emission is a radiance, OBJ's Ke an exitance) with
  KHR_materials_emissive_strength when a component exceeds 1 [3.9];
- faces without a material get a primitive without one.
"""
import base64
import json
import math
import os
import struct
import sys


def parse_mtl(path, materials, order):
    cur = None
    base = os.path.dirname(path)
    try:
        lines = open(path, encoding="utf-8", errors="replace").read().splitlines()
    except OSError:
        return
    for line in lines:
        w = line.strip().split()
        if not w:
            continue
        if w[0] == "newmtl":
            cur = line.strip()[6:].strip()
            materials[cur] = {}
            order.append(cur)
        elif cur is None:
            continue
        elif w[0] in ("Kd", "Ke"):
            vals = [float(x) for x in w[1:4]]
            if len(vals) == 1:
                vals = vals * 3
            materials[cur][w[0]] = vals
        elif w[0] == "map_Kd":
            spec = line.strip()[6:].strip()
            name = spec.split()[-1] if spec.startswith("-") else spec
            materials[cur]["map_Kd"] = os.path.join(base, name.replace("\\", "/"))


def parse_obj(path):
    v, vt, vn = [], [], []
    runs = []  # [material or None, [faces]]; a face is [(vi, ti, ni), ...]
    materials, order = {}, []
    current = None
    base = os.path.dirname(path)
    for line in open(path, encoding="utf-8", errors="replace"):
        w = line.split()
        if not w:
            continue
        k = w[0]
        if k == "v":
            v.append([float(x) for x in w[1:4]])
        elif k == "vt":
            vt.append([float(x) for x in w[1:3]])
        elif k == "vn":
            vn.append([float(x) for x in w[1:4]])
        elif k == "mtllib":
            parse_mtl(os.path.join(base, line.strip()[6:].strip()), materials, order)
        elif k == "usemtl":
            name = line.strip()[6:].strip()
            current = name if name in materials else None
        elif k == "f":
            face = []
            for tok in w[1:]:
                parts = tok.split("/")
                idx = []
                for j, arr in enumerate((v, vt, vn)):
                    if j < len(parts) and parts[j]:
                        i = int(parts[j])
                        idx.append(i - 1 if i > 0 else len(arr) + i)
                    else:
                        idx.append(None)
                face.append(tuple(idx))
            if len(face) < 3:
                continue
            if not runs or runs[-1][0] != current:
                runs.append([current, []])
            runs[-1][1].append(face)
    return v, vt, vn, runs, materials, order


class Bin:
    def __init__(self):
        self.data = bytearray()
        self.views = []

    def add(self, payload, target=None):
        while len(self.data) % 4:
            self.data.append(0)
        view = {"buffer": 0, "byteOffset": len(self.data), "byteLength": len(payload)}
        if target:
            view["target"] = target
        self.data += payload
        self.views.append(view)
        return len(self.views) - 1


def convert(obj, out):
    v, vt, vn, runs, materials, order = parse_obj(obj)
    glb = out.lower().endswith(".glb")
    out_dir = os.path.dirname(os.path.abspath(out))
    b = Bin()
    accessors, prims = [], []
    mat_index = {name: i for i, name in enumerate(order)}

    def accessor(values, kind, comps, target, minmax=False):
        fmt = "<%d%s" % (len(values) * comps, "I" if kind == 5125 else "f")
        flat = [x for item in values for x in (item if comps > 1 else [item])]
        view = b.add(struct.pack(fmt, *flat), target)
        a = {"bufferView": view, "componentType": kind, "count": len(values),
             "type": {1: "SCALAR", 2: "VEC2", 3: "VEC3"}[comps]}
        if minmax:
            a["min"] = [min(p[c] for p in values) for c in range(comps)]
            a["max"] = [max(p[c] for p in values) for c in range(comps)]
        accessors.append(a)
        return len(accessors) - 1

    for material, faces in runs:
        has_t = all(c[1] is not None for f in faces for c in f)
        has_n = all(c[2] is not None for f in faces for c in f)
        key_of = {}
        pos, nrm, uv, idx = [], [], [], []
        for f in faces:
            ids = []
            for c in f:
                key = (c[0], c[1] if has_t else None, c[2] if has_n else None)
                if key not in key_of:
                    key_of[key] = len(pos)
                    pos.append(v[c[0]])
                    if has_t:
                        uv.append([vt[c[1]][0], 1.0 - vt[c[1]][1]])
                    if has_n:
                        nrm.append(vn[c[2]])
                ids.append(key_of[key])
            for i in range(1, len(ids) - 1):
                idx += [ids[0], ids[i], ids[i + 1]]
        attrs = {"POSITION": accessor(pos, 5126, 3, 34962, True)}
        if has_n:
            attrs["NORMAL"] = accessor(nrm, 5126, 3, 34962)
        if has_t:
            attrs["TEXCOORD_0"] = accessor(uv, 5126, 2, 34962)
        prim = {"attributes": attrs, "indices": accessor(idx, 5125, 1, 34963), "mode": 4}
        if material is not None:
            prim["material"] = mat_index[material]
        prims.append(prim)

    images, textures, mats = [], [], []
    used_ext = set()
    for name in order:
        m = materials[name]
        tex = m.get("map_Kd")
        if tex is not None and not os.path.isfile(tex):
            tex = None
        kd = m.get("Kd", [1.0] * 3 if tex else [0.8] * 3)
        pbr = {"baseColorFactor": kd + [1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0}
        if tex:
            if glb:
                mime = "image/png" if tex.lower().endswith(".png") else "image/jpeg"
                images.append({"bufferView": b.add(open(tex, "rb").read()), "mimeType": mime})
            else:
                rel = os.path.relpath(os.path.abspath(tex), out_dir).replace(os.sep, "/")
                images.append({"uri": rel.replace(" ", "%20")})
            textures.append({"source": len(images) - 1, "sampler": 0})
            pbr["baseColorTexture"] = {"index": len(textures) - 1}
        mat = {"name": name, "pbrMetallicRoughness": pbr}
        ke = m.get("Ke", [0.0] * 3)
        if any(x > 0 for x in ke):
            radiance = [x / math.pi for x in ke]
            peak = max(radiance)
            if peak > 1.0:
                mat["emissiveFactor"] = [x / peak for x in radiance]
                mat["extensions"] = {"KHR_materials_emissive_strength": {"emissiveStrength": peak}}
                used_ext.add("KHR_materials_emissive_strength")
            else:
                mat["emissiveFactor"] = radiance
        mats.append(mat)

    doc = {
        "asset": {"version": "2.0", "generator": "radiosity scripts/obj2gltf.py"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": os.path.basename(obj)}],
        "meshes": [{"primitives": prims}],
        "accessors": accessors,
        "bufferViews": b.views,
        "buffers": [{"byteLength": len(b.data)}],
    }
    if mats:
        doc["materials"] = mats
    if textures:
        doc["textures"] = textures
        doc["images"] = images
        doc["samplers"] = [{"wrapS": 10497, "wrapT": 10497}]
    if used_ext:
        doc["extensionsUsed"] = sorted(used_ext)
    if glb:
        while len(b.data) % 4:
            b.data.append(0)
        text = json.dumps(doc).encode()
        text += b" " * ((4 - len(text) % 4) % 4)
        total = 12 + 8 + len(text) + 8 + len(b.data)
        with open(out, "wb") as f:
            f.write(struct.pack("<4sII", b"glTF", 2, total))
            f.write(struct.pack("<I4s", len(text), b"JSON") + text)
            f.write(struct.pack("<I4s", len(b.data), b"BIN\0") + bytes(b.data))
    else:
        bin_name = os.path.splitext(os.path.basename(out))[0] + ".bin"
        doc["buffers"][0]["uri"] = bin_name.replace(" ", "%20")
        with open(os.path.join(out_dir, bin_name), "wb") as f:
            f.write(bytes(b.data))
        with open(out, "w") as f:
            json.dump(doc, f)


if __name__ == "__main__":
    if len(sys.argv) != 3 or sys.argv[1] in ("-h", "--help"):
        print(__doc__.strip())
        sys.exit(0 if len(sys.argv) == 2 else 2)
    convert(sys.argv[1], sys.argv[2])
