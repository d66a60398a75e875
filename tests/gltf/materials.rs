//! Materials and textures: texture sets, transforms and samplers, metal,
//! textured emission, double-sided baking, a textured room rendered alike.

use super::builder::*;
use super::common::{bake_config, bake_to, temp_dir};
use radiosity::bake::voxelize::Resolution;
use radiosity::core::scene::{self, srgb_to_linear, Wrap};
use radiosity::runtime::{Runtime, RuntimeOptions};
use serde_json::json;
use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

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
