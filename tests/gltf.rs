//! glTF 2.0 scenes (src/core/scene/gltf): files written here, by hand with
//! a small builder (node transforms, a mirror, strips and fans, texture
//! coordinate sets and transforms, lights and a camera, broken files) or by
//! `scripts/obj2gltf.py` (an independent Python converter) from the OBJ
//! scenes, whose bakes must then match the OBJ's. Expected values are
//! computed by hand from the spec: transforms, photometric units
//! (683 lm/W), the emissive radiance as exitance (`π L`), the texture
//! transform's example.

mod common;

use base64::Engine as _;
use common::{bake_config, bake_to, temp_dir};
use radiosity::bake::voxelize::Resolution;
use radiosity::core::light::incident;
use radiosity::core::scene::{self, srgb_to_linear, Scene, Wrap};
use radiosity::core::scene_config::Light;
use radiosity::runtime::{Runtime, RuntimeOptions};
use serde_json::{json, Value};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

// ---------------------------------------------------------------------------
// A glTF builder

/// A glTF document under construction: its JSON and one binary buffer.
struct Builder {
    json: Value,
    bin: Vec<u8>,
}

impl Builder {
    fn new() -> Builder {
        Builder {
            json: json!({"asset": {"version": "2.0"}}),
            bin: Vec::new(),
        }
    }

    /// Appends `item` to the top-level array `key`; its index.
    fn push(&mut self, key: &str, item: Value) -> usize {
        let list = self.json[key].as_array_mut().map(|a| {
            a.push(item.clone());
            a.len() - 1
        });
        list.unwrap_or_else(|| {
            self.json[key] = json!([item]);
            0
        })
    }

    /// A buffer view over `bytes` (4-byte aligned).
    fn view(&mut self, bytes: &[u8]) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.push(
            "bufferViews",
            json!({"buffer": 0, "byteOffset": offset, "byteLength": bytes.len()}),
        )
    }

    fn floats<const N: usize>(&mut self, data: &[[f32; N]]) -> usize {
        let bytes: Vec<u8> = data
            .iter()
            .flatten()
            .flat_map(|f| f.to_le_bytes())
            .collect();
        let view = self.view(&bytes);
        let kind = ["SCALAR", "VEC2", "VEC3", "VEC4"][N - 1];
        let mut a =
            json!({"bufferView": view, "componentType": 5126, "count": data.len(), "type": kind});
        if N == 3 {
            let lo: Vec<f32> = (0..N)
                .map(|k| data.iter().map(|p| p[k]).fold(f32::INFINITY, f32::min))
                .collect();
            let hi: Vec<f32> = (0..N)
                .map(|k| data.iter().map(|p| p[k]).fold(f32::NEG_INFINITY, f32::max))
                .collect();
            a["min"] = json!(lo);
            a["max"] = json!(hi);
        }
        self.push("accessors", a)
    }

    fn indices(&mut self, idx: &[u32]) -> usize {
        let bytes: Vec<u8> = idx.iter().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.view(&bytes);
        self.push(
            "accessors",
            json!({"bufferView": view, "componentType": 5125, "count": idx.len(), "type": "SCALAR"}),
        )
    }

    /// A mesh of one primitive per `(attributes, indices, mode, material)`.
    fn mesh(&mut self, prims: Vec<Value>) -> usize {
        self.push("meshes", json!({"primitives": prims}))
    }

    /// An embedded PNG texture image (bufferView); the texture's index.
    fn png_texture(&mut self, png: &[u8], sampler: Value) -> usize {
        let view = self.view(png);
        let image = self.push(
            "images",
            json!({"bufferView": view, "mimeType": "image/png"}),
        );
        let s = self.push("samplers", sampler);
        self.push("textures", json!({"source": image, "sampler": s}))
    }

    fn finish_json(&self, uri: Option<&str>) -> Value {
        let mut j = self.json.clone();
        let mut buffer = json!({"byteLength": self.bin.len()});
        if let Some(u) = uri {
            buffer["uri"] = json!(u);
        }
        j["buffers"] = json!([buffer]);
        j
    }

    /// Writes a `.gltf` with the buffer as a data URI.
    fn write_gltf(&self, path: &Path) {
        let uri = format!(
            "data:application/octet-stream;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(&self.bin)
        );
        std::fs::write(path, self.finish_json(Some(&uri)).to_string()).unwrap();
    }

    /// Writes a `.glb` (JSON chunk, BIN chunk).
    fn glb_bytes(&self) -> Vec<u8> {
        let mut text = self.finish_json(None).to_string().into_bytes();
        while !text.len().is_multiple_of(4) {
            text.push(b' ');
        }
        let mut bin = self.bin.clone();
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let total = 12 + 8 + text.len() + 8 + bin.len();
        let mut out = Vec::new();
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(text.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&text);
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
        out
    }
}

/// The unit quad `[0, 1]²` in the `z = 0` plane facing `+z`, indexed, as a
/// primitive (with NORMAL), and optionally `material`.
fn unit_quad(b: &mut Builder, material: Option<usize>) -> Value {
    let pos = b.floats(&[
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ]);
    let nrm = b.floats(&[[0.0, 0.0, 1.0f32]; 4]);
    let idx = b.indices(&[0, 1, 2, 0, 2, 3]);
    let mut p = json!({"attributes": {"POSITION": pos, "NORMAL": nrm}, "indices": idx});
    if let Some(m) = material {
        p["material"] = json!(m);
    }
    p
}

/// A 2 × 2 RGB PNG of the given sRGB pixels (row-major).
fn png(pixels: [[u8; 3]; 4]) -> Vec<u8> {
    let img = image::RgbImage::from_fn(2, 2, |x, y| image::Rgb(pixels[(2 * y + x) as usize]));
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

/// The three corners of triangle `t`.
fn corners(s: &Scene, t: usize) -> [[f32; 3]; 3] {
    s.triangles[t].map(|v| s.positions[v as usize])
}

fn close3(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
    (0..3).all(|k| (a[k] - b[k]).abs() <= tol)
}

fn load_err(path: &Path) -> String {
    match scene::load(path) {
        Ok(_) => panic!("{} loaded; it should fail", path.display()),
        Err(e) => e.to_string(),
    }
}

/// `scripts/obj2gltf.py obj out` (the independent converter).
fn convert(obj: &Path, out: &Path) {
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scripts/obj2gltf.py");
    let status = Command::new("python3")
        .arg(&script)
        .arg(obj)
        .arg(out)
        .status()
        .unwrap_or_else(|e| {
            panic!(
                "running python3 {} (scripts/setup installs python3): {e}",
                script.display()
            )
        });
    assert!(status.success(), "obj2gltf.py failed on {}", obj.display());
}

// ---------------------------------------------------------------------------
// Geometry

#[test]
fn node_transforms_and_a_mirror_place_the_triangles_front_side_out() {
    let dir = temp_dir("gltf-nodes");
    let mut b = Builder::new();
    let quad = unit_quad(&mut b, None);
    let mesh = b.mesh(vec![quad]);
    let h = std::f64::consts::FRAC_1_SQRT_2;
    // 0: translate (10, 0, 0), child 1: turned 90° about +y. 2: mirrored
    // in x. 3: a matrix moving it up 5 (column-major).
    b.push(
        "nodes",
        json!({"translation": [10.0, 0.0, 0.0], "children": [1]}),
    );
    b.push("nodes", json!({"rotation": [0.0, h, 0.0, h], "mesh": mesh}));
    b.push("nodes", json!({"scale": [-1.0, 1.0, 1.0], "mesh": mesh}));
    b.push(
        "nodes",
        json!({"matrix": [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 5.0, 0.0, 1.0], "mesh": mesh}),
    );
    b.push("scenes", json!({"nodes": [0, 2, 3]}));
    b.json["scene"] = json!(0);
    let path = dir.join("nodes.gltf");
    b.write_gltf(&path);
    let s = scene::load(&path).unwrap();
    assert_eq!(s.triangle_count(), 6);
    // Rotation about +y by 90°: (x, y, z) → (z, y, −x); then +10 in x.
    let rot = |p: [f64; 3]| [p[2] + 10.0, p[1], -p[0]];
    let quad_pts = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];
    let expect: [Vec<[f64; 3]>; 3] = [
        quad_pts.iter().map(|&p| rot(p)).collect(),
        quad_pts.iter().map(|p| [-p[0], p[1], p[2]]).collect(),
        quad_pts.iter().map(|p| [p[0], p[1] + 5.0, p[2]]).collect(),
    ];
    let normals = [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]];
    for (k, (pts, n)) in expect.iter().zip(normals).enumerate() {
        for t in [2 * k, 2 * k + 1] {
            for c in corners(&s, t) {
                let c = c.map(f64::from);
                assert!(
                    pts.iter().any(|p| close3(*p, c, 1e-6)),
                    "node {k}: corner {c:?} is not one of {pts:?}"
                );
            }
            // The front stays the front, the mirror included.
            assert!(
                close3(s.triangle_normal(t), n, 1e-6),
                "node {k} triangle {t}: normal {:?}, expected {n:?}",
                s.triangle_normal(t)
            );
            assert!((s.triangle_area(t) - 0.5).abs() < 1e-6);
        }
    }
    // The vertex normals went through the inverse transpose: none
    // disagrees with its triangle's winding.
    assert_eq!(s.repairs.winding_disagrees_with_normals, 0);
    assert!(
        s.warnings.iter().any(|w| w.contains("no material")),
        "{:?}",
        s.warnings
    );
}

#[test]
fn strips_fans_unindexed_primitives_and_ignored_points() {
    let dir = temp_dir("gltf-modes");
    let mut b = Builder::new();
    // A strip over the unit square at z = 0, a fan at z = 1 without
    // indices, and a points primitive.
    let strip_pos = b.floats(&[
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 0.0f32],
    ]);
    let fan_pos = b.floats(&[
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 1.0],
        [1.0, 1.0, 1.0],
        [0.0, 1.0, 1.0f32],
    ]);
    let mesh = b.mesh(vec![
        json!({"attributes": {"POSITION": strip_pos}, "mode": 5}),
        json!({"attributes": {"POSITION": fan_pos}, "mode": 6}),
        json!({"attributes": {"POSITION": fan_pos}, "mode": 0}),
    ]);
    b.push("nodes", json!({"mesh": mesh}));
    b.push("scenes", json!({"nodes": [0]}));
    let path = dir.join("modes.glb");
    std::fs::write(&path, b.glb_bytes()).unwrap();
    let s = scene::load(&path).unwrap();
    assert_eq!(
        s.triangle_count(),
        4,
        "two from the strip, two from the fan"
    );
    for t in 0..4 {
        assert!(
            close3(s.triangle_normal(t), [0.0, 0.0, 1.0], 1e-9),
            "triangle {t}"
        );
    }
    assert!((s.surface_area() - 2.0).abs() < 1e-9);
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("1 point or line primitive")),
        "{:?}",
        s.warnings
    );
}

#[test]
fn obj_and_gltf_bake_to_the_same_patches_and_transfer() {
    let dir = temp_dir("gltf-same");
    let obj = common::bundled("cornell_box");
    let glb = dir.join("cornell.glb");
    let gltf = dir.join("cornell.gltf");
    convert(&obj, &glb);
    convert(&obj, &gltf);
    let res = Resolution::Patches(300);
    let (_, a) = bake_to(bake_config(&obj, res), &dir.join("obj.rad"));
    for path in [&glb, &gltf] {
        let (_, b) = bake_to(bake_config(path, res), &dir.join("gltf.rad"));
        assert_eq!(a.patches.len(), b.patches.len());
        for (p, q) in a.patches.iter().zip(&b.patches) {
            // The same f32 vertices in the same order: the same patches.
            assert_eq!(
                (p.centre, p.normal, p.area, p.albedo),
                (q.centre, q.normal, q.area, q.albedo)
            );
            assert_eq!(p.voxel, q.voxel);
            // Ke went through Ke/π and back: f32 rounding, a few ulps.
            assert!(close3(
                p.emission,
                q.emission,
                1e-6 * p.emission[0].abs().max(1.0)
            ));
        }
        // The same patches and albedos give the same matrix; the solve
        // is deterministic, so only rounding in the emission (not in H's
        // inputs) could differ: none.
        for ch in 0..3 {
            assert_eq!(
                a.transfer.channel(ch),
                b.transfer.channel(ch),
                "{} channel {ch}",
                path.display()
            );
        }
    }
}

#[test]
fn sponza_as_gltf_loads_to_the_objs_geometry_and_materials() {
    let dir = temp_dir("gltf-sponza");
    let obj = common::sponza();
    let glb = dir.join("sponza.glb");
    convert(&obj, &glb);
    let a = scene::load(&obj).unwrap();
    let b = scene::load(&glb).unwrap();
    assert_eq!(a.triangle_count(), b.triangle_count());
    for t in 0..a.triangle_count() {
        assert_eq!(corners(&a, t), corners(&b, t), "triangle {t}");
        let (ma, mb) = (
            &a.materials[a.triangle_material[t] as usize],
            &b.materials[b.triangle_material[t] as usize],
        );
        assert_eq!(ma.name, mb.name);
    }
    for (ma, mb) in a.materials.iter().zip(&b.materials) {
        // The same texture bytes (a file, embedded in the .glb), the same
        // Kd: the same albedo.
        assert!(
            close3(ma.albedo.map(f64::from), mb.albedo.map(f64::from), 1e-7),
            "{}",
            ma.name
        );
        assert_eq!(
            ma.diffuse_texture.is_some(),
            mb.diffuse_texture.is_some(),
            "{}",
            ma.name
        );
    }
    // Texture coordinates: v flipped twice (1 − (1 − v)), rounding only.
    for t in 0..a.triangle_count() {
        for (va, vb) in a.triangles[t].iter().zip(&b.triangles[t]) {
            let textured = a.materials[a.triangle_material[t] as usize]
                .diffuse_texture
                .is_some();
            if textured && !a.texcoords.is_empty() {
                let (ua, ub) = (a.texcoords[*va as usize], b.texcoords[*vb as usize]);
                assert!(
                    (ua[0] - ub[0]).abs() < 1e-6 && (ua[1] - ub[1]).abs() < 1e-5,
                    "{ua:?} {ub:?}"
                );
            }
        }
    }
}

// ---------------------------------------------------------------------------
// Materials and textures

#[test]
fn texture_sets_transforms_and_samplers_reach_the_run_time() {
    let dir = temp_dir("gltf-uv");
    let mut b = Builder::new();
    let tex = b.png_texture(
        &png([[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 255]]),
        json!({"wrapS": 33071, "wrapT": 33648}),
    );
    b.push(
        "materials",
        json!({"name": "tiles", "pbrMetallicRoughness": {
            "baseColorFactor": [0.5, 0.5, 0.5, 1.0], "metallicFactor": 0.0,
            "baseColorTexture": {"index": tex, "texCoord": 0, "extensions": {"KHR_texture_transform": {
                "offset": [0.5, 0.0], "scale": [2.0, 2.0], "texCoord": 1}}}}}),
    );
    b.json["extensionsUsed"] = json!(["KHR_texture_transform"]);
    let pos = b.floats(&[
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0f32],
    ]);
    let uv0 = b.floats(&[[0.0, 0.0f32]; 4]);
    let uv1 = b.floats(&[[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0f32]]);
    let idx = b.indices(&[0, 1, 2, 0, 2, 3]);
    let mesh = b.mesh(vec![json!({"attributes": {"POSITION": pos, "TEXCOORD_0": uv0, "TEXCOORD_1": uv1}, "indices": idx, "material": 0})]);
    b.push("nodes", json!({"mesh": mesh}));
    b.push("scenes", json!({"nodes": [0]}));
    let path = dir.join("uv.glb");
    std::fs::write(&path, b.glb_bytes()).unwrap();
    let s = scene::load(&path).unwrap();
    let m = &s.materials[0];
    let t = m.diffuse_texture.as_ref().expect("the texture is kept");
    assert_eq!(t.wrap, [Wrap::ClampToEdge, Wrap::MirroredRepeat]);
    // Albedo: the factor times the linear mean of the four texels.
    let mean: Vec<f64> = (0..3)
        .map(|c| {
            let px = [[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 255]];
            px.iter()
                .map(|p: &[u8; 3]| srgb_to_linear(f64::from(p[c]) / 255.0))
                .sum::<f64>()
                / 4.0
        })
        .collect();
    for (a, t) in m.albedo.iter().zip(&mean) {
        assert!((f64::from(*a) - 0.5 * t).abs() < 1e-6);
    }
    // TEXCOORD_1 (the transform's override), scaled by 2, offset by
    // (0.5, 0), then v flipped: glTF (u, v) → (2u + 0.5, 1 − 2v).
    let uv1_vals = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];
    for (v, p) in s.positions.iter().enumerate() {
        let k = match (p[0] as i32, p[1] as i32) {
            (0, 0) => 0,
            (1, 0) => 1,
            (1, 1) => 2,
            _ => 3,
        };
        let [u, w] = uv1_vals[k];
        let want = [2.0 * u + 0.5, 1.0 - 2.0 * w];
        let got = s.texcoords[v];
        assert!(
            (f64::from(got[0]) - want[0]).abs() < 1e-6
                && (f64::from(got[1]) - want[1]).abs() < 1e-6,
            "vertex {p:?}: {got:?}, expected {want:?}"
        );
    }
    // The run time samples the embedded image with the sampler's wraps:
    // clamped in s (u = 5 reads the right column), mirrored in t.
    let tex = radiosity::runtime::texture::Texture::load(t).unwrap();
    let right_top = tex.sample([0.99, 0.99]);
    let far_right = tex.sample([5.0, 0.99]);
    for c in 0..3 {
        assert!(
            (right_top[c] - far_right[c]).abs() < 0.02,
            "{right_top:?} {far_right:?}"
        );
    }
    let mirrored = tex.sample([0.25, 1.25]);
    let inside = tex.sample([0.25, 0.75]);
    for c in 0..3 {
        assert!(
            (mirrored[c] - inside[c]).abs() < 1e-5,
            "{mirrored:?} {inside:?}"
        );
    }
}

#[test]
fn metal_and_ignored_features_are_said_and_albedo_follows_one_minus_metallic() {
    let dir = temp_dir("gltf-metal");
    let mut b = Builder::new();
    b.push(
        "materials",
        json!({"name": "brass", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.6, 0.2, 1.0], "metallicFactor": 0.75, "roughnessFactor": 0.3},
               "alphaMode": "BLEND"}),
    );
    let quad = unit_quad(&mut b, Some(0));
    let mesh = b.mesh(vec![quad]);
    b.push("nodes", json!({"mesh": mesh}));
    b.push("scenes", json!({"nodes": [0]}));
    let path = dir.join("metal.gltf");
    b.write_gltf(&path);
    let s = scene::load(&path).unwrap();
    let want = [0.8 * 0.25, 0.6 * 0.25, 0.2 * 0.25];
    assert!(
        close3(s.materials[0].albedo.map(f64::from), want, 1e-6),
        "{:?}",
        s.materials[0].albedo
    );
    let note: Vec<&String> = s
        .warnings
        .iter()
        .filter(|w| w.contains("`brass`"))
        .collect();
    assert_eq!(note.len(), 1, "one note for the material: {:?}", s.warnings);
    for part in ["metal", "alpha blending", "glossy"] {
        assert!(note[0].contains(part), "{part} not said: {}", note[0]);
    }
}

/// A closed 2 m room (inward quads of albedo 0.5) with an emissive quad
/// under the ceiling facing down; `emitter` is its material (index 1).
fn room(b: &mut Builder, emitter: Value) -> usize {
    b.push("materials", json!({"name": "wall", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0], "metallicFactor": 0.0}}));
    b.push("materials", emitter);
    let mut prims = Vec::new();
    // Inward faces of [0, 2]³: for each axis and side, a quad.
    for axis in 0..3 {
        for side in [0.0f32, 2.0] {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let mut pts = Vec::new();
            for (a, c) in [(0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0f32)] {
                let mut p = [0.0f32; 3];
                p[axis] = side;
                p[u] = a;
                p[v] = c;
                pts.push(p);
            }
            // u × v = axis: counter-clockwise seen from +axis; inward at
            // side 0 is +axis, at side 2 reversed.
            let idx = if side == 0.0 {
                [0, 1, 2, 0, 2, 3]
            } else {
                [0, 2, 1, 0, 3, 2]
            };
            let pos = b.floats(&pts);
            let i = b.indices(&idx);
            prims.push(json!({"attributes": {"POSITION": pos}, "indices": i, "material": 0}));
        }
    }
    // The emitter: 0.5 m square at y = 1.9, facing −y.
    let pos = b.floats(&[
        [0.75, 1.9, 0.75],
        [1.25, 1.9, 0.75],
        [1.25, 1.9, 1.25],
        [0.75, 1.9, 1.25f32],
    ]);
    let i = b.indices(&[0, 1, 2, 0, 2, 3]);
    prims.push(json!({"attributes": {"POSITION": pos}, "indices": i, "material": 1}));
    b.mesh(prims)
}

#[test]
fn a_textured_emissive_quad_lights_the_room_with_its_textures_mean_power() {
    let dir = temp_dir("gltf-emissive");
    let pixels = [[255, 255, 255], [0, 0, 0], [188, 100, 40], [128, 128, 128]];
    let mean: [f64; 3] = std::array::from_fn(|c| {
        pixels
            .iter()
            .map(|p: &[u8; 3]| srgb_to_linear(f64::from(p[c]) / 255.0))
            .sum::<f64>()
            / 4.0
    });
    let factor = [1.0, 0.5, 0.25];
    let strength = 3.0;
    // The expected exitance: π × factor × strength × mean (module doc).
    let ke: [f64; 3] =
        std::array::from_fn(|c| std::f64::consts::PI * factor[c] * strength * mean[c]);

    let mut b = Builder::new();
    let tex = b.png_texture(&png(pixels), json!({}));
    let mesh = room(
        &mut b,
        json!({"name": "lamp", "emissiveFactor": factor, "emissiveTexture": {"index": tex},
               "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": strength}},
               "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0], "metallicFactor": 0.0}}),
    );
    b.json["extensionsUsed"] = json!(["KHR_materials_emissive_strength"]);
    b.push("nodes", json!({"mesh": mesh}));
    b.push("scenes", json!({"nodes": [0]}));
    let textured = dir.join("textured.glb");
    std::fs::write(&textured, b.glb_bytes()).unwrap();
    let s = scene::load(&textured).unwrap();
    let lamp = s.materials.iter().find(|m| m.name == "lamp").unwrap();
    assert!(
        close3(lamp.emission.map(f64::from), ke, 1e-5 * ke[0]),
        "{:?} vs {ke:?}",
        lamp.emission
    );

    // The same room whose lamp has the constant exitance Ke, written as
    // an OBJ: the run time's radiosity must be the same.
    let mut obj = String::from("mtllib r.mtl\n");
    let mut vcount = 0;
    for (t, tri) in s.triangles.iter().enumerate() {
        let m = &s.materials[s.triangle_material[t] as usize];
        obj += &format!("usemtl {}\n", m.name);
        for &v in tri {
            let p = s.positions[v as usize];
            obj += &format!("v {:?} {:?} {:?}\n", p[0], p[1], p[2]);
        }
        obj += &format!("f {} {} {}\n", vcount + 1, vcount + 2, vcount + 3);
        vcount += 3;
    }
    std::fs::write(dir.join("r.obj"), obj).unwrap();
    std::fs::write(
        dir.join("r.mtl"),
        format!(
            "newmtl wall\nKd 0.5 0.5 0.5\nnewmtl lamp\nKd 0.5 0.5 0.5\nKe {} {} {}\n",
            ke[0], ke[1], ke[2]
        ),
    )
    .unwrap();
    let res = Resolution::Patches(120);
    let h = |scene_path: &Path, out: &str| -> [Vec<f32>; 3] {
        let (baked, _) = bake_to(bake_config(scene_path, res), &dir.join(out));
        let scene = scene::load(scene_path).unwrap();
        let mut rt = Runtime::new(baked, scene, RuntimeOptions::default());
        rt.frame(&[], &BTreeMap::new());
        rt.h().clone()
    };
    let a = h(&textured, "glb.rad");
    let b = h(&dir.join("r.obj"), "obj.rad");
    let (mut d, mut r, mut lit) = (0.0f64, 0.0f64, 0usize);
    for c in 0..3 {
        for (x, y) in a[c].iter().zip(&b[c]) {
            d = d.max(f64::from((x - y).abs()));
            r = r.max(f64::from(y.abs()));
            lit += usize::from(*x > 0.0);
        }
    }
    assert!(r > 0.0 && lit > a[0].len(), "the room is lit");
    // Same patches, emission equal to f32 rounding (1e-5 relative above).
    assert!(d <= 1e-4 * r, "largest difference {d} of {r}");
}

#[test]
fn double_sided_materials_are_baked_with_back_sides() {
    let dir = temp_dir("gltf-double");
    let mut b = Builder::new();
    let mesh = room(
        &mut b,
        json!({"name": "lamp", "emissiveFactor": [1.0, 1.0, 1.0],
               "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0], "metallicFactor": 0.0}}),
    );
    // A double-sided partition standing in the room.
    b.push("materials", json!({"name": "screen", "doubleSided": true, "pbrMetallicRoughness": {"baseColorFactor": [0.7, 0.7, 0.7, 1.0], "metallicFactor": 0.0}}));
    let quad = unit_quad(&mut b, Some(2));
    let screen = b.mesh(vec![quad]);
    b.push("nodes", json!({"mesh": mesh}));
    b.push(
        "nodes",
        json!({"mesh": screen, "translation": [0.5, 0.2, 1.0]}),
    );
    b.push("scenes", json!({"nodes": [0, 1]}));
    let path = dir.join("double.glb");
    std::fs::write(&path, b.glb_bytes()).unwrap();
    let s = scene::load(&path).unwrap();
    let screen_tris: Vec<u32> = (0..s.triangle_count() as u32)
        .filter(|&t| s.materials[s.triangle_material[t as usize] as usize].double_sided)
        .collect();
    assert_eq!(screen_tris.len(), 2);
    let mut c = bake_config(&path, Resolution::Patches(150));
    c.as_wound = true;
    let (baked, out) = bake_to(c, &dir.join("double.rad"));
    assert_eq!(
        baked.options.twinned, screen_tris,
        "as wound: the double-sided faces only"
    );
    assert_eq!(out.report.winding.double_sided, 2);
    // Patches on both sides of the screen (normals ±z at z = 1).
    let sides: Vec<f64> = out
        .patches
        .iter()
        .filter(|p| (p.centre[2] - 1.0).abs() < 1e-3 && p.normal[2].abs() > 0.99)
        .map(|p| p.normal[2])
        .collect();
    assert!(
        sides.iter().any(|&z| z > 0.0) && sides.iter().any(|&z| z < 0.0),
        "{sides:?}"
    );
}

/// Reads a PFM's pixels (as `radiosity render --hdr` writes them).
fn read_pfm(path: &Path) -> Vec<f32> {
    let bytes = std::fs::read(path).unwrap();
    let mut lines = 0;
    let mut at = 0;
    while lines < 3 {
        if bytes[at] == b'\n' {
            lines += 1;
        }
        at += 1;
    }
    bytes[at..]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

fn rel_rms(a: &[f32], b: &[f32]) -> f64 {
    assert_eq!(a.len(), b.len());
    let (mut d, mut r) = (0.0f64, 0.0f64);
    for (x, y) in a.iter().zip(b) {
        d += f64::from(x - y).powi(2);
        r += f64::from(*y).powi(2);
    }
    assert!(r > 0.0, "a black image");
    (d / r).sqrt()
}

#[test]
fn a_textured_room_renders_the_same_from_obj_gltf_and_glb_on_cpu_and_gl() {
    let dir = temp_dir("gltf-render");
    // A 4 × 4 texture of distinct colours, in a file whose name has a
    // space (a percent-escaped URI in the .gltf).
    std::fs::create_dir_all(dir.join("tex")).unwrap();
    let img = image::RgbImage::from_fn(4, 4, |x, y| {
        image::Rgb([(60 * x + 20) as u8, (60 * y + 20) as u8, 200])
    });
    img.save(dir.join("tex/floor tiles.png")).unwrap();
    // The room [0, 2]³ seen from inside; the floor's texture repeats twice.
    let mut obj = String::from("mtllib room.mtl\n");
    obj += "v 0 0 0\nv 2 0 0\nv 2 0 2\nv 0 0 2\nv 0 2 0\nv 2 2 0\nv 2 2 2\nv 0 2 2\n";
    obj += "vt 0 0\nvt 2 0\nvt 2 2\nvt 0 2\n";
    obj += "usemtl floor\nf 1/1 4/4 3/3 2/2\n";
    obj += "usemtl wall\nf 5 6 7 8\nf 1 2 6 5\nf 3 4 8 7\nf 1 5 8 4\nf 2 3 7 6\n";
    std::fs::write(dir.join("room.obj"), obj).unwrap();
    std::fs::write(
        dir.join("room.mtl"),
        "newmtl floor\nKd 0.9 0.9 0.9\nmap_Kd tex/floor tiles.png\nnewmtl wall\nKd 0.6 0.5 0.4\n",
    )
    .unwrap();
    let lights = dir.join("view.json");
    std::fs::write(
        &lights,
        r#"{"camera": {"position": [1.0, 1.6, 1.9], "target": [1.0, 0.0, 0.6], "up": [0, 1, 0], "fov_y_deg": 70},
            "lights": [{"type": "point", "position": [1.2, 1.7, 0.8], "intensity": [2, 2, 2]}], "units": "m"}"#,
    )
    .unwrap();
    let glb = dir.join("room.glb");
    let gltf = dir.join("room.gltf");
    convert(&dir.join("room.obj"), &glb);
    convert(&dir.join("room.obj"), &gltf);
    let text = std::fs::read_to_string(&gltf).unwrap();
    assert!(
        text.contains("tex/floor%20tiles.png"),
        "the converter escapes the URI"
    );
    let bin = env!("CARGO_BIN_EXE_radiosity");
    let render = |scene: &Path, backend: &str| -> Vec<f32> {
        let hdr = dir.join(format!(
            "{}-{backend}.pfm",
            scene.file_name().unwrap().to_string_lossy()
        ));
        let out = Command::new(bin)
            .env("RADIOSITY_CACHE_DIR", dir.join("cache"))
            .args([
                "render",
                scene.to_str().unwrap(),
                "--patches",
                "100",
                "--backend",
                backend,
            ])
            .args([
                "--camera-lights",
                lights.to_str().unwrap(),
                "--width",
                "96",
                "--height",
                "72",
            ])
            .args([
                "-o",
                dir.join("x.png").to_str().unwrap(),
                "--hdr",
                hdr.to_str().unwrap(),
            ])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}: {}",
            scene.display(),
            String::from_utf8_lossy(&out.stderr)
        );
        read_pfm(&hdr)
    };
    for backend in ["cpu", "gl"] {
        let reference = render(&dir.join("room.obj"), backend);
        for scene in [&glb, &gltf] {
            let e = rel_rms(&render(scene, backend), &reference);
            eprintln!(
                "{backend} {}: relative RMS {e:.3e} against the OBJ",
                scene.display()
            );
            // The same bake and the same texels; the texture coordinates
            // differ by the rounding of 1 − (1 − v) in f32 (1e-7 of the
            // texture), which moves a bilinear sample by far less than
            // 1e-4 of the image.
            assert!(e < 1e-4, "{backend} {}: relative RMS {e}", scene.display());
        }
    }
}

// ---------------------------------------------------------------------------
// Lights and camera

#[test]
fn lights_convert_photometric_units_and_the_camera_is_the_start_view() {
    let dir = temp_dir("gltf-lights");
    let mut b = Builder::new();
    // A floor: the unit quad turned to face +y (rotation −90° about x:
    // +z → +y), centred under the lights.
    let quad = unit_quad(&mut b, None);
    let mesh = b.mesh(vec![quad]);
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let down = json!([-h, 0.0, 0.0, h]); // −z → −y
    b.json["extensionsUsed"] = json!(["KHR_lights_punctual"]);
    b.json["extensions"] = json!({"KHR_lights_punctual": {"lights": [
        {"type": "point", "intensity": 683.0, "color": [1.0, 0.5, 0.25]},
        {"type": "spot", "intensity": 1366.0, "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.5}, "range": 10.0},
        {"type": "directional", "intensity": 1366.0}
    ]}});
    b.push(
        "nodes",
        json!({"mesh": mesh, "translation": [-0.5, 0.0, 0.5], "rotation": [-h, 0.0, 0.0, h]}),
    );
    b.push("nodes", json!({"translation": [0.0, 2.0, 0.0], "extensions": {"KHR_lights_punctual": {"light": 0}}}));
    b.push("nodes", json!({"translation": [0.0, 3.0, 0.0], "rotation": down, "extensions": {"KHR_lights_punctual": {"light": 1}}}));
    b.push(
        "nodes",
        json!({"rotation": down, "extensions": {"KHR_lights_punctual": {"light": 2}}}),
    );
    b.push(
        "cameras",
        json!({"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}),
    );
    b.push(
        "nodes",
        json!({"translation": [0.0, 1.0, 5.0], "camera": 0}),
    );
    b.push("scenes", json!({"nodes": [0, 1, 2, 3, 4]}));
    let path = dir.join("lit.gltf");
    b.write_gltf(&path);
    let s = scene::load(&path).unwrap();
    // The quaternion's numbers are read as f32: 1e-7 rounding.
    assert!(close3(s.triangle_normal(0), [0.0, 1.0, 0.0], 1e-6));
    assert_eq!(s.authored.lights.len(), 3);
    assert!(
        s.warnings.iter().any(|w| w.contains("range")),
        "{:?}",
        s.warnings
    );
    // Irradiance at the floor's centre (0, 0, 0) facing up, by hand:
    // point 683 cd / 683 at 2 m: 1/4 W/m² × colour; spot 1366 cd on its
    // axis at 3 m: 2/9; sun of 1366 lx straight down: 2 W/m².
    let x = [0.0, 0.0, 0.0];
    let n = [0.0, 1.0, 0.0];
    let e = |l: &Light| {
        incident(l, x, n, 100.0)
            .map(|i| i.irradiance)
            .unwrap_or([0.0; 3])
    };
    let want = [[0.25, 0.125, 0.0625], [2.0 / 9.0; 3], [2.0; 3]];
    for (l, w) in s.authored.lights.iter().zip(want) {
        assert!(close3(e(l), w, 1e-6), "{l:?}: {:?} vs {w:?}", e(l));
    }
    match &s.authored.lights[1] {
        Light::Spot {
            cone_angle_deg,
            beam_angle_deg,
            ..
        } => {
            assert!((f64::from(*cone_angle_deg) - 0.5f64.to_degrees()).abs() < 1e-4);
            assert!((f64::from(*beam_angle_deg) - 0.2f64.to_degrees()).abs() < 1e-4);
        }
        other => panic!("{other:?}"),
    }
    // The camera, and the configuration a command starts from.
    let config = radiosity::core::default_view::config_for(&s);
    let c = &config.camera;
    assert!(close3(c.position.map(f64::from), [0.0, 1.0, 5.0], 1e-6));
    let d: Vec<f64> = (0..3)
        .map(|k| f64::from(c.target[k] - c.position[k]))
        .collect();
    assert!(
        d[0].abs() < 1e-6 && d[1].abs() < 1e-6 && d[2] < 0.0,
        "looks down −z: {d:?}"
    );
    assert!((f64::from(c.fov_y_deg) - 0.8f64.to_degrees()).abs() < 1e-4);
    assert_eq!(config.lights, s.authored.lights);
    assert!(
        config.description.contains("lit.gltf"),
        "{}",
        config.description
    );
}

#[test]
fn view_and_render_use_the_files_camera_and_lights_and_a_json_overrides_them() {
    let dir = temp_dir("gltf-cli");
    let mut b = Builder::new();
    let mesh = room(
        &mut b,
        json!({"name": "lamp", "emissiveFactor": [0.0, 0.0, 0.0],
               "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0], "metallicFactor": 0.0}}),
    );
    b.json["extensionsUsed"] = json!(["KHR_lights_punctual"]);
    b.json["extensions"] =
        json!({"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 100.0}]}});
    b.push("nodes", json!({"mesh": mesh}));
    b.push("nodes", json!({"translation": [1.0, 1.5, 1.0], "extensions": {"KHR_lights_punctual": {"light": 0}}}));
    b.push(
        "cameras",
        json!({"type": "perspective", "perspective": {"yfov": 1.0, "znear": 0.01}}),
    );
    b.push(
        "nodes",
        json!({"translation": [1.0, 1.0, 1.9], "camera": 0}),
    );
    b.push("scenes", json!({"nodes": [0, 1, 2]}));
    let glb = dir.join("room.glb");
    std::fs::write(&glb, b.glb_bytes()).unwrap();
    let bin = env!("CARGO_BIN_EXE_radiosity");
    let run = |args: &[&str]| {
        let out = Command::new(bin).args(args).output().unwrap();
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        )
    };
    let rad = dir.join("room.rad");
    let said = run(&[
        "bake",
        glb.to_str().unwrap(),
        "--patches",
        "100",
        "-o",
        rad.to_str().unwrap(),
    ]);
    // The voxel size in metres, the unit glTF fixes.
    assert!(said.contains(" m, grid "), "{said}");
    let png = dir.join("a.png");
    let said = run(&[
        "render",
        rad.to_str().unwrap(),
        "-o",
        png.to_str().unwrap(),
        "--width",
        "64",
        "--height",
        "48",
    ]);
    assert!(
        said.contains("the camera and 1 light(s) of room.glb"),
        "{said}"
    );
    // A camera-and-lights file beside the scene wins.
    std::fs::write(
        dir.join("room.json"),
        r#"{"camera": {"position": [1, 1, 1], "target": [0, 1, 1], "up": [0, 1, 0], "fov_y_deg": 60},
            "lights": [{"type": "point", "position": [1, 1.5, 1], "intensity": [1, 1, 1]}], "units": "m"}"#,
    )
    .unwrap();
    let said = run(&[
        "render",
        rad.to_str().unwrap(),
        "-o",
        png.to_str().unwrap(),
        "--width",
        "64",
        "--height",
        "48",
    ]);
    assert!(!said.contains("light(s) of room.glb"), "{said}");
    // The Mitsuba export takes it too: the room's meshes and its light.
    let said = run(&[
        "export-mitsuba",
        glb.to_str().unwrap(),
        "-o",
        dir.join("mitsuba").to_str().unwrap(),
    ]);
    assert!(said.contains("1 lights"), "{said}");
    assert!(dir.join("mitsuba/scene.xml").is_file());
    // `info` on the .glb reports metres and the file's view.
    let out = Command::new(bin)
        .args(["info", glb.to_str().unwrap()])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("(metres)") && text.contains("a camera, 1 light(s) from the file"),
        "{text}"
    );
}

// ---------------------------------------------------------------------------
// Bad files

/// A valid one-quad `.glb`'s bytes, for the broken variants.
fn valid_glb() -> Vec<u8> {
    let mut b = Builder::new();
    let quad = unit_quad(&mut b, None);
    let mesh = b.mesh(vec![quad]);
    b.push("nodes", json!({"mesh": mesh}));
    b.push("scenes", json!({"nodes": [0]}));
    b.glb_bytes()
}

#[test]
fn broken_files_are_errors_that_say_what_is_wrong() {
    let dir = temp_dir("gltf-bad");
    let write = |name: &str, text: &str| -> PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    };
    let base = |extra: Value| -> Value {
        let mut b = Builder::new();
        let quad = unit_quad(&mut b, None);
        let mesh = b.mesh(vec![quad]);
        b.push("nodes", json!({"mesh": mesh}));
        b.push("scenes", json!({"nodes": [0]}));
        let mut j = b.finish_json(Some(&format!(
            "data:application/octet-stream;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(&b.bin)
        )));
        if let Value::Object(m) = extra {
            for (k, v) in m {
                j[k] = v;
            }
        }
        j
    };
    // A missing buffer file.
    let mut j = base(json!({}));
    j["buffers"][0]["uri"] = json!("gone.bin");
    let e = load_err(&write("missing.gltf", &j.to_string()));
    assert!(e.contains("buffer 0") && e.contains("gone.bin"), "{e}");
    // An accessor reaching past its data.
    let mut j = base(json!({}));
    j["accessors"][0]["count"] = json!(400);
    let e = load_err(&write("long.gltf", &j.to_string()));
    assert!(
        e.contains("POSITION (accessor 0)") && e.contains("400 elements"),
        "{e}"
    );
    // An index past the vertices: the indices' view rewritten to hold 7.
    let mut b = Builder::new();
    let pos = b.floats(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0f32]]);
    let idx = b.indices(&[0, 1, 7]);
    let mesh = b.mesh(vec![
        json!({"attributes": {"POSITION": pos}, "indices": idx}),
    ]);
    b.push("nodes", json!({"mesh": mesh}));
    b.push("scenes", json!({"nodes": [0]}));
    let p = dir.join("index.glb");
    std::fs::write(&p, b.glb_bytes()).unwrap();
    let e = load_err(&p);
    assert!(
        e.contains("index 2 is 7") && e.contains("meshes[0].primitives[0] indices"),
        "{e}"
    );
    // A texture that is not an image.
    let mut b = Builder::new();
    let tex = b.png_texture(b"not a png at all", json!({}));
    b.push(
        "materials",
        json!({"name": "broken", "pbrMetallicRoughness": {"baseColorTexture": {"index": tex}}}),
    );
    let quad = unit_quad(&mut b, Some(0));
    let mesh = b.mesh(vec![quad]);
    b.push("nodes", json!({"mesh": mesh}));
    b.push("scenes", json!({"nodes": [0]}));
    let p = dir.join("texture.glb");
    std::fs::write(&p, b.glb_bytes()).unwrap();
    let e = load_err(&p);
    assert!(
        e.contains("`broken`") && e.contains("baseColorTexture") && e.contains("image 0"),
        "{e}"
    );
    // A compression extension the loader cannot read.
    let j = base(
        json!({"extensionsUsed": ["KHR_draco_mesh_compression"], "extensionsRequired": ["KHR_draco_mesh_compression"]}),
    );
    let e = load_err(&write("draco.gltf", &j.to_string()));
    assert!(
        e.contains("KHR_draco_mesh_compression") && e.contains("Draco"),
        "{e}"
    );
    // Not JSON: the line is named.
    let e = load_err(&write(
        "syntax.gltf",
        "{\n  \"asset\": {\"version\": \"2.0\"},\n  oops\n}",
    ));
    assert!(e.contains("syntax.gltf:3"), "{e}");
    // A node cycle.
    let j = base(json!({"nodes": [{"mesh": 0, "children": [1]}, {"children": [0]}]}));
    let e = load_err(&write("cycle.gltf", &j.to_string()));
    assert!(e.contains("node"), "{e}");
    // A truncated .glb.
    let glb = valid_glb();
    let p = dir.join("short.glb");
    std::fs::write(&p, &glb[..glb.len() / 2]).unwrap();
    let e = load_err(&p);
    assert!(e.contains("short.glb"), "{e}");
    // The command: exit status 1 and the file named, no panic.
    let out = Command::new(env!("CARGO_BIN_EXE_radiosity"))
        .args(["info", p.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("short.glb") && !stderr.contains("panicked"),
        "{stderr}"
    );
}

/// A `.glb` using most of what the loader reads: a node tree with a
/// mirror, an embedded texture with a sampler and a transform, a metallic
/// double-sided material, a strip, lights and a camera.
fn rich_glb() -> Vec<u8> {
    let mut b = Builder::new();
    let tex = b.png_texture(
        &png([[255, 0, 0], [0, 255, 0], [0, 0, 255], [9, 9, 9]]),
        json!({"wrapS": 33071}),
    );
    b.push(
        "materials",
        json!({"name": "m", "doubleSided": true, "emissiveFactor": [0.1, 0.1, 0.1],
               "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0], "metallicFactor": 0.5,
               "baseColorTexture": {"index": tex, "extensions": {"KHR_texture_transform": {"scale": [2.0, 2.0]}}}}}),
    );
    let pos = b.floats(&[
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 0.0f32],
    ]);
    let uv = b.floats(&[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0f32]]);
    let quad = unit_quad(&mut b, Some(0));
    let mesh = b.mesh(vec![
        quad,
        json!({"attributes": {"POSITION": pos, "TEXCOORD_0": uv}, "mode": 5, "material": 0}),
    ]);
    b.json["extensionsUsed"] = json!(["KHR_lights_punctual", "KHR_texture_transform"]);
    b.json["extensions"] = json!({"KHR_lights_punctual": {"lights": [
        {"type": "spot", "intensity": 10.0, "spot": {"outerConeAngle": 0.5}}, {"type": "point", "intensity": 5.0}]}});
    b.push(
        "cameras",
        json!({"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}),
    );
    b.push(
        "nodes",
        json!({"translation": [0.0, 1.0, 0.0], "children": [1, 2]}),
    );
    b.push("nodes", json!({"mesh": mesh, "scale": [-1.0, 1.0, 1.0]}));
    b.push("nodes", json!({"camera": 0, "translation": [0.0, 0.0, 3.0], "extensions": {"KHR_lights_punctual": {"light": 0}}}));
    b.push("nodes", json!({"translation": [0.0, 2.0, 0.0], "extensions": {"KHR_lights_punctual": {"light": 1}}}));
    b.push("scenes", json!({"nodes": [0, 3]}));
    b.glb_bytes()
}

#[test]
fn mutated_files_never_panic() {
    // Deterministic mutations (bytes set, cuts) of two valid .glb files,
    // as the bake file's corruption tests do: every one loads or is an
    // error. GLTF_FUZZ_CASES runs more (30,000 ran clean, 2026-12-04).
    let dir = temp_dir("gltf-fuzz");
    let cases: usize = std::env::var("GLTF_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(400);
    let rich = rich_glb();
    assert!(scene::load(&{
        let p = dir.join("rich.glb");
        std::fs::write(&p, &rich).unwrap();
        p
    })
    .is_ok());
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let p = dir.join("m.glb");
    for (k, base) in [valid_glb(), rich].iter().enumerate() {
        for case in 0..cases {
            let mut bytes = base.clone();
            for _ in 0..1 + case % 4 {
                let at = (next() % bytes.len() as u64) as usize;
                bytes[at] = match next() % 3 {
                    // Digits and JSON punctuation reach deeper than noise.
                    0 => b"0123456789-.e,]}"[(next() % 16) as usize],
                    _ => (next() & 0xff) as u8,
                };
            }
            if case % 5 == 0 {
                bytes.truncate((next() % bytes.len() as u64) as usize);
            }
            std::fs::write(&p, &bytes).unwrap();
            match std::panic::catch_unwind(|| scene::load(&p).map(|s| s.triangle_count())) {
                Ok(Ok(_)) | Ok(Err(_)) => {}
                Err(_) => panic!("file {k} case {case} panicked"),
            }
        }
    }
}
