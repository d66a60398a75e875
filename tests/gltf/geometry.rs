//! Geometry: node transforms and a mirror, primitive modes, and the same
//! scene as OBJ and glTF baked and loaded alike.

use super::builder::*;
use super::common::{self, bake_config, bake_to, temp_dir};
use radiosity::bake::voxelize::Resolution;
use radiosity::core::scene;
use serde_json::json;

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
