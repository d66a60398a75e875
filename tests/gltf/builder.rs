//! A glTF builder for the tests (JSON and one buffer, written as `.gltf`
//! with a data URI or as `.glb`), small scenes and the checks they share.

#![allow(dead_code)]

use base64::Engine as _;
use radiosity::core::scene::{self, Scene};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::process::Command;

// ---------------------------------------------------------------------------
// A glTF builder

/// A glTF document under construction: its JSON and one binary buffer.
pub struct Builder {
    pub json: Value,
    pub bin: Vec<u8>,
}

impl Builder {
    pub fn new() -> Builder {
        Builder {
            json: json!({"asset": {"version": "2.0"}}),
            bin: Vec::new(),
        }
    }

    /// Appends `item` to the top-level array `key`; its index.
    pub fn push(&mut self, key: &str, item: Value) -> usize {
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
    pub fn view(&mut self, bytes: &[u8]) -> usize {
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

    pub fn floats<const N: usize>(&mut self, data: &[[f32; N]]) -> usize {
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

    pub fn indices(&mut self, idx: &[u32]) -> usize {
        let bytes: Vec<u8> = idx.iter().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.view(&bytes);
        self.push(
            "accessors",
            json!({"bufferView": view, "componentType": 5125, "count": idx.len(), "type": "SCALAR"}),
        )
    }

    /// A mesh of one primitive per `(attributes, indices, mode, material)`.
    pub fn mesh(&mut self, prims: Vec<Value>) -> usize {
        self.push("meshes", json!({"primitives": prims}))
    }

    /// An embedded PNG texture image (bufferView); the texture's index.
    pub fn png_texture(&mut self, png: &[u8], sampler: Value) -> usize {
        let view = self.view(png);
        let image = self.push(
            "images",
            json!({"bufferView": view, "mimeType": "image/png"}),
        );
        let s = self.push("samplers", sampler);
        self.push("textures", json!({"source": image, "sampler": s}))
    }

    pub fn finish_json(&self, uri: Option<&str>) -> Value {
        let mut j = self.json.clone();
        let mut buffer = json!({"byteLength": self.bin.len()});
        if let Some(u) = uri {
            buffer["uri"] = json!(u);
        }
        j["buffers"] = json!([buffer]);
        j
    }

    /// Writes a `.gltf` with the buffer as a data URI.
    pub fn write_gltf(&self, path: &Path) {
        let uri = format!(
            "data:application/octet-stream;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(&self.bin)
        );
        std::fs::write(path, self.finish_json(Some(&uri)).to_string()).unwrap();
    }

    /// Writes a `.glb` (JSON chunk, BIN chunk).
    pub fn glb_bytes(&self) -> Vec<u8> {
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
pub fn unit_quad(b: &mut Builder, material: Option<usize>) -> Value {
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
pub fn png(pixels: [[u8; 3]; 4]) -> Vec<u8> {
    let img = image::RgbImage::from_fn(2, 2, |x, y| image::Rgb(pixels[(2 * y + x) as usize]));
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

/// The three corners of triangle `t`.
pub fn corners(s: &Scene, t: usize) -> [[f32; 3]; 3] {
    s.triangles[t].map(|v| s.positions[v as usize])
}

pub fn close3(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
    (0..3).all(|k| (a[k] - b[k]).abs() <= tol)
}

pub fn load_err(path: &Path) -> String {
    match scene::load(path) {
        Ok(_) => panic!("{} loaded; it should fail", path.display()),
        Err(e) => e.to_string(),
    }
}

/// `scripts/obj2gltf.py obj out` (the independent converter).
pub fn convert(obj: &Path, out: &Path) {
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

/// A closed 2 m room (inward quads of albedo 0.5) with an emissive quad
/// under the ceiling facing down; `emitter` is its material (index 1).
pub fn room(b: &mut Builder, emitter: Value) -> usize {
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
