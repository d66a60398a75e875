//! Bad files: errors that name what is wrong, and mutations that never
//! panic.

use super::builder::*;
use super::common::temp_dir;
use base64::Engine as _;
use radiosity::core::scene;
use serde_json::{json, Value};
use std::path::PathBuf;
use std::process::Command;

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
