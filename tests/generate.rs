//! Tests of the bundled scene generators (`radiosity::generate`) and of the
//! camera/lights file (`radiosity::core::scene_config`).
//!
//! The committed files under `scenes/` must equal what the generator writes
//! now. To regenerate them after changing a generator, run
//! `RADIOSITY_REGENERATE_SCENES=1 cargo test --test generate committed_scenes`
//! (or `cargo run --release -- generate NAME -o scenes/NAME` per scene).

use glam::DVec3;
use radiosity::core::scene_config::{self, Camera, ConfigError, Light, SceneConfig};
use radiosity::generate::{
    build, coaxial_disks_factor, parallel_rectangles_factor, perpendicular_rectangles_factor,
    write_bundled, GenerateError, GeneratedScene, BUNDLED,
};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes")
}

/// A fresh temporary directory unique to this process and `tag`.
fn temp_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "radiosity-test-generate-{}-{tag}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn scene(name: &str) -> GeneratedScene {
    build(name).unwrap_or_else(|e| panic!("building {name}: {e}"))
}

// ---------------------------------------------------------------------------
// Committed files

#[test]
fn committed_scenes_match_generator() {
    let regenerate = std::env::var("RADIOSITY_REGENERATE_SCENES").is_ok_and(|v| v == "1");
    for name in BUNDLED {
        let committed = scenes_dir().join(name);
        if regenerate {
            let written = write_bundled(name, &committed).unwrap();
            assert_eq!(written.len(), 3);
        }
        let fresh = temp_dir(name);
        let written = write_bundled(name, &fresh).unwrap();
        let expected: Vec<PathBuf> = ["obj", "mtl", "json"]
            .iter()
            .map(|e| fresh.join(format!("{name}.{e}")))
            .collect();
        assert_eq!(written, expected);
        let mut listed: Vec<String> = std::fs::read_dir(&committed)
            .unwrap_or_else(|e| panic!("{}: {e}; regenerate the scenes", committed.display()))
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        listed.sort();
        let mut want: Vec<String> = ["obj", "mtl", "json"]
            .iter()
            .map(|e| format!("{name}.{e}"))
            .collect();
        want.sort();
        assert_eq!(listed, want, "files under {}", committed.display());
        for path in &written {
            let file = path.file_name().unwrap();
            let old = std::fs::read(committed.join(file)).unwrap();
            let new = std::fs::read(path).unwrap();
            assert!(
                old == new,
                "scenes/{name}/{} differs from what the generator writes now; regenerate with \
                 RADIOSITY_REGENERATE_SCENES=1 cargo test --test generate committed_scenes",
                file.to_string_lossy()
            );
        }
        std::fs::remove_dir_all(&fresh).unwrap();
    }
    assert!(
        scenes_dir().join("README.md").is_file(),
        "scenes/README.md documents the scenes"
    );
}

#[test]
fn unknown_scene_names_the_known_ones() {
    let err = build("sponza").unwrap_err();
    assert!(matches!(err, GenerateError::UnknownScene { .. }));
    let msg = err.to_string();
    for name in BUNDLED {
        assert!(msg.contains(name), "{msg}");
    }
    let dir = temp_dir("unknown");
    assert!(write_bundled("nope", &dir).is_err());
    assert_eq!(
        std::fs::read_dir(&dir).unwrap().count(),
        0,
        "nothing written for an unknown scene"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn written_files_parse_back_to_the_mesh() {
    // The OBJ's text reproduces the in-memory mesh exactly: positions as
    // printed parse to the stored values, faces and materials match.
    let s = scene("cornell_box");
    let obj = s.obj_text();
    let mut positions = Vec::new();
    let mut faces = Vec::new();
    let mut current = String::new();
    let mut mtllib = None;
    for line in obj.lines() {
        let mut w = line.split_whitespace();
        match w.next() {
            Some("v") => positions.push([0; 3].map(|_| w.next().unwrap().parse::<f64>().unwrap())),
            Some("f") => {
                let idx: Vec<u32> = w.map(|x| x.parse::<u32>().unwrap() - 1).collect();
                assert_eq!(idx.len(), 3);
                faces.push(([idx[0], idx[1], idx[2]], current.clone()));
            }
            Some("usemtl") => current = w.next().unwrap().to_string(),
            Some("mtllib") => mtllib = Some(w.next().unwrap().to_string()),
            _ => {}
        }
    }
    assert_eq!(mtllib.as_deref(), Some("cornell_box.mtl"));
    assert_eq!(positions, s.mesh.positions);
    assert_eq!(faces.len(), s.mesh.triangles.len());
    for (t, (f, m)) in faces.iter().enumerate() {
        assert_eq!(*f, s.mesh.triangles[t]);
        assert_eq!(*m, s.materials[s.mesh.triangle_material[t] as usize].name);
    }
    let mtl = s.mtl_text();
    assert!(
        mtl.contains("newmtl light\nKd 0.78 0.78 0.78\nKe 17 12 4\n"),
        "{mtl}"
    );
    assert!(
        mtl.contains("newmtl white\nKd 0.725 0.71 0.68\nKe 0 0 0\n"),
        "{mtl}"
    );
}

// ---------------------------------------------------------------------------
// Cornell box

/// The published vertex lists of the Cornell Box Data page.
const PUBLISHED: &[[f64; 3]] = &[
    // floor
    [552.8, 0.0, 0.0],
    [0.0, 0.0, 0.0],
    [0.0, 0.0, 559.2],
    [549.6, 0.0, 559.2],
    // light (also the ceiling's hole)
    [343.0, 548.8, 227.0],
    [343.0, 548.8, 332.0],
    [213.0, 548.8, 332.0],
    [213.0, 548.8, 227.0],
    // ceiling
    [556.0, 548.8, 0.0],
    [556.0, 548.8, 559.2],
    [0.0, 548.8, 559.2],
    [0.0, 548.8, 0.0],
    // back wall
    [549.6, 0.0, 559.2],
    [0.0, 0.0, 559.2],
    [0.0, 548.8, 559.2],
    [556.0, 548.8, 559.2],
    // right wall (green)
    [0.0, 0.0, 559.2],
    [0.0, 0.0, 0.0],
    [0.0, 548.8, 0.0],
    [0.0, 548.8, 559.2],
    // left wall (red)
    [552.8, 0.0, 0.0],
    [549.6, 0.0, 559.2],
    [556.0, 548.8, 559.2],
    [556.0, 548.8, 0.0],
    // short block
    [130.0, 165.0, 65.0],
    [82.0, 165.0, 225.0],
    [240.0, 165.0, 272.0],
    [290.0, 165.0, 114.0],
    [290.0, 0.0, 114.0],
    [240.0, 0.0, 272.0],
    [130.0, 0.0, 65.0],
    [82.0, 0.0, 225.0],
    // tall block
    [423.0, 330.0, 247.0],
    [265.0, 330.0, 296.0],
    [314.0, 330.0, 456.0],
    [472.0, 330.0, 406.0],
    [423.0, 0.0, 247.0],
    [472.0, 0.0, 406.0],
    [314.0, 0.0, 456.0],
    [265.0, 0.0, 296.0],
];

const SHORT_TOP: [[f64; 2]; 4] = [[130.0, 65.0], [82.0, 225.0], [240.0, 272.0], [290.0, 114.0]];
const TALL_TOP: [[f64; 2]; 4] = [
    [423.0, 247.0],
    [265.0, 296.0],
    [314.0, 456.0],
    [472.0, 406.0],
];

/// Whether `(x, z)` lies strictly inside the convex polygon `poly`.
fn in_convex(poly: &[[f64; 2]; 4], x: f64, z: f64) -> bool {
    let sides: Vec<f64> = (0..4)
        .map(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % 4]);
            (b[0] - a[0]) * (z - a[1]) - (b[1] - a[1]) * (x - a[0])
        })
        .collect();
    sides.iter().all(|&s| s > 0.0) || sides.iter().all(|&s| s < 0.0)
}

/// The red wall's x at height y and depth z (bilinear through its corners).
fn left_wall_x(y: f64, z: f64) -> f64 {
    let (t, s) = (y / 548.8, z / 559.2);
    (1.0 - t) * ((1.0 - s) * 552.8 + s * 549.6) + t * 556.0
}

/// The box's open space: inside the walls, floor and ceiling (open at the
/// front, z = 0) and outside both blocks.
fn in_open_space(p: DVec3) -> bool {
    let in_box = p.y > 0.0
        && p.y < 548.8
        && p.z > 0.0
        && p.z < 559.2
        && p.x > 0.0
        && p.x < left_wall_x(p.y, p.z);
    let in_short = p.y < 165.0 && in_convex(&SHORT_TOP, p.x, p.z);
    let in_tall = p.y < 330.0 && in_convex(&TALL_TOP, p.x, p.z);
    in_box && !in_short && !in_tall
}

#[test]
fn cornell_box_keeps_the_published_coordinates() {
    let s = scene("cornell_box");
    assert_eq!(s.config.units, "mm");
    for p in PUBLISHED {
        assert!(
            s.mesh.positions.contains(p),
            "published vertex {p:?} missing"
        );
    }
    let obj = s.obj_text();
    for line in [
        "v 343.0000 548.8000 227.0000",
        "v 552.8000 0.0000 0.0000",
        "v 472.0000 330.0000 406.0000",
    ] {
        assert!(obj.lines().any(|l| l == line), "{line} not in the OBJ");
    }
    // Every coordinate stays inside the published extents.
    let (lo, hi) = s.mesh.bounds();
    assert_eq!(lo.to_array(), [0.0, 0.0, 0.0]);
    assert_eq!(hi.to_array(), [556.0, 548.8, 559.2]);
}

/// Each triangle's front (1 mm along its normal from its centroid) lies in
/// the open space and its back does not: walls, floor and ceiling face
/// into the box, the blocks face out of themselves. The one exception is
/// the published floor, which runs under the blocks standing on it: there
/// its front is inside a block, so for floor triangles the front is only
/// required to be inside the box and the normal to be +y.
#[test]
fn cornell_box_surfaces_face_into_the_open_space() {
    let s = scene("cornell_box");
    let mut under_blocks = 0;
    for t in 0..s.mesh.triangles.len() {
        let c = s.mesh.centroid(t);
        let n = s.mesh.normal(t);
        let on_floor = s.mesh.corners(t).iter().all(|p| p.y == 0.0);
        if on_floor && !in_open_space(c + n) {
            assert_eq!(n.to_array(), [0.0, 1.0, 0.0]);
            let p = c + n;
            assert!(
                p.y < 165.0 && (in_convex(&SHORT_TOP, p.x, p.z) || in_convex(&TALL_TOP, p.x, p.z))
            );
            under_blocks += 1;
            continue;
        }
        assert!(
            in_open_space(c + n),
            "triangle {t} at {c:?} faces {n:?}: its front is not in the open space"
        );
        assert!(
            !in_open_space(c - n),
            "triangle {t} at {c:?} faces {n:?}: its back is in the open space"
        );
    }
    assert!(
        under_blocks > 0 && under_blocks < 60,
        "{under_blocks} floor triangles under the blocks"
    );
}

#[test]
fn cornell_box_materials_light_and_camera() {
    let s = scene("cornell_box");
    let names: Vec<&str> = s.materials.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["white", "red", "green", "light"]);
    assert_eq!(s.materials[0].kd, [0.725, 0.71, 0.68]);
    assert_eq!(s.materials[1].kd, [0.63, 0.065, 0.05]);
    assert_eq!(s.materials[2].kd, [0.14, 0.45, 0.091]);
    assert_eq!(s.materials[3].kd, [0.78, 0.78, 0.78]);
    assert_eq!(s.materials[3].ke, [17.0, 12.0, 4.0]);
    for m in &s.materials[..3] {
        assert_eq!(m.ke, [0.0; 3]);
    }
    let light = s.material_index("light").unwrap();
    let area = s.mesh.material_area(light);
    assert!((area - 130.0 * 105.0).abs() < 1e-6, "light area {area}");
    for t in 0..s.mesh.triangles.len() {
        if s.mesh.triangle_material[t] == light {
            assert_eq!(s.mesh.normal(t).to_array(), [0.0, -1.0, 0.0]);
            for p in s.mesh.corners(t) {
                assert_eq!(p.y, 548.8);
            }
        }
    }
    // The ceiling has the hole: its area is the rectangle's minus the light's.
    let white = s.material_index("white").unwrap();
    let ceiling: f64 = (0..s.mesh.triangles.len())
        .filter(|&t| s.mesh.triangle_material[t] == white && s.mesh.normal(t).y < -0.99)
        .map(|t| s.mesh.area(t))
        .sum();
    assert!(
        (ceiling - (556.0 * 559.2 - 130.0 * 105.0)).abs() < 1e-6,
        "ceiling area {ceiling}"
    );
    let cam = &s.config.camera;
    assert_eq!(cam.position, [278.0, 273.0, -800.0]);
    assert_eq!(cam.up, [0.0, 1.0, 0.0]);
    let view = DVec3::from_array(cam.target.map(f64::from))
        - DVec3::from_array(cam.position.map(f64::from));
    assert!(view.x == 0.0 && view.y == 0.0 && view.z > 0.0);
    let fov = 2.0 * (0.0125f64 / 0.035).atan().to_degrees();
    assert!(
        (cam.fov_y_deg as f64 - fov).abs() < 1e-4,
        "fov {}",
        cam.fov_y_deg
    );
    match s.config.lights.as_slice() {
        [Light::Spot {
            position,
            direction,
            ..
        }] => {
            assert_eq!(*direction, [0.0, -1.0, 0.0]);
            assert!(position[1] < 548.8 && position[1] > 540.0);
            assert!(
                position[0] > 213.0
                    && position[0] < 343.0
                    && position[2] > 227.0
                    && position[2] < 332.0
            );
        }
        other => panic!("expected one spot light, got {other:?}"),
    }
}

// ---------------------------------------------------------------------------
// Analytic scenes

/// Total area and the set of distinct unit normals of a material.
fn area_and_normals(s: &GeneratedScene, name: &str) -> (f64, Vec<[f64; 3]>) {
    let m = s.material_index(name).unwrap();
    let mut normals: Vec<[f64; 3]> = Vec::new();
    let mut area = 0.0;
    for t in 0..s.mesh.triangles.len() {
        if s.mesh.triangle_material[t] == m {
            area += s.mesh.area(t);
            let n = s
                .mesh
                .normal(t)
                .to_array()
                .map(|x| (x * 1e9).round() / 1e9 + 0.0);
            if !normals.contains(&n) {
                normals.push(n);
            }
        }
    }
    (area, normals)
}

/// Every triangle of `from` faces every triangle of `to` (the other's
/// centroid is in front of it).
fn faces_towards(s: &GeneratedScene, from: &str, to: &str) -> bool {
    let (a, b) = (
        s.material_index(from).unwrap(),
        s.material_index(to).unwrap(),
    );
    let tris =
        |m: u32| (0..s.mesh.triangles.len()).filter(move |&t| s.mesh.triangle_material[t] == m);
    tris(a).all(|t| {
        tris(b).all(|u| {
            s.mesh
                .normal(t)
                .dot(s.mesh.centroid(u) - s.mesh.centroid(t))
                > 0.0
        })
    })
}

#[test]
fn analytic_factors_match_the_catalog_values() {
    assert!((parallel_rectangles_factor(1.0, 1.0, 1.0) - 0.199825).abs() < 1e-6);
    assert!((perpendicular_rectangles_factor(1.0, 1.0, 1.0) - 0.200044).abs() < 1e-6);
    assert!((coaxial_disks_factor(1.0, 1.0, 1.0) - 0.381966).abs() < 1e-6);
    assert!((coaxial_disks_factor(1.0, 1.0, 1.0) - (3.0 - 5f64.sqrt()) / 2.0).abs() < 1e-12);
    // Reciprocity of the unequal-disk formula: A1 F12 = A2 F21.
    let (r1, r2, h) = (0.5, 1.5, 0.8);
    let lhs = r1 * r1 * coaxial_disks_factor(r1, r2, h);
    let rhs = r2 * r2 * coaxial_disks_factor(r2, r1, h);
    assert!((lhs - rhs).abs() < 1e-12);
}

#[test]
fn parallel_squares_are_unit_and_opposed() {
    let s = scene("parallel_squares");
    let (ae, ne) = area_and_normals(&s, "emitter");
    let (ar, nr) = area_and_normals(&s, "receiver");
    assert!(
        (ae - 1.0).abs() < 1e-12 && (ar - 1.0).abs() < 1e-12,
        "{ae} {ar}"
    );
    assert_eq!(ne, vec![[0.0, 1.0, 0.0]]);
    assert_eq!(nr, vec![[0.0, -1.0, 0.0]]);
    assert!(faces_towards(&s, "emitter", "receiver") && faces_towards(&s, "receiver", "emitter"));
    let (lo, hi) = s.mesh.bounds();
    assert_eq!((lo.to_array(), hi.to_array()), ([0.0; 3], [1.0; 3]));
    assert!(
        s.mesh.triangles.len() >= 8,
        "each square split into a few cells"
    );
}

#[test]
fn perpendicular_squares_share_an_edge_and_face_the_gap() {
    let s = scene("perpendicular_squares");
    let (ae, ne) = area_and_normals(&s, "emitter");
    let (ar, nr) = area_and_normals(&s, "receiver");
    assert!(
        (ae - 1.0).abs() < 1e-12 && (ar - 1.0).abs() < 1e-12,
        "{ae} {ar}"
    );
    assert_eq!(ne, vec![[0.0, 1.0, 0.0]]);
    assert_eq!(nr, vec![[0.0, 0.0, 1.0]]);
    // Both lie in the quadrant y >= 0, z >= 0 and meet along y = z = 0.
    for p in &s.mesh.positions {
        assert!(p[1] >= 0.0 && p[2] >= 0.0 && (p[1] == 0.0 || p[2] == 0.0));
    }
    assert!(
        s.mesh.positions.contains(&[0.0, 0.0, 0.0]) && s.mesh.positions.contains(&[1.0, 0.0, 0.0])
    );
    // Facing the space between them: every front points into the quadrant.
    for t in 0..s.mesh.triangles.len() {
        let p = s.mesh.centroid(t) + s.mesh.normal(t) * 0.01;
        assert!(p.y > 0.0 && p.z > 0.0);
    }
}

#[test]
fn coaxial_disks_are_128_gons_with_the_polygon_area() {
    let s = scene("coaxial_disks");
    let polygon = 64.0 * (std::f64::consts::PI / 64.0).sin();
    for name in ["emitter", "receiver"] {
        let (a, normals) = area_and_normals(&s, name);
        assert!((a - polygon).abs() < 1e-5, "{name}: {a} vs {polygon}");
        let deficit = 1.0 - a / std::f64::consts::PI;
        assert!(
            (deficit - 4.015e-4).abs() < 2e-6,
            "{name}: area deficit {deficit}"
        );
        assert_eq!(normals.len(), 1);
    }
    assert_eq!(s.mesh.triangles.len(), 2 * 128);
    assert_eq!(area_and_normals(&s, "emitter").1, vec![[0.0, 1.0, 0.0]]);
    assert_eq!(area_and_normals(&s, "receiver").1, vec![[0.0, -1.0, 0.0]]);
    assert!(faces_towards(&s, "emitter", "receiver") && faces_towards(&s, "receiver", "emitter"));
    for p in &s.mesh.positions {
        let r = (p[0] * p[0] + p[2] * p[2]).sqrt();
        assert!(r < 1e-12 || (r - 1.0).abs() < 1e-6, "radius {r}");
        assert!(p[1] == 0.0 || p[1] == 1.0);
    }
    // The polygon's effect on the factor, for the record: true disks of the
    // same area (radius sqrt(A/π)) have F = 0.381897, 6.9e-5 (0.018 %)
    // below the unit disks' 0.381966.
    let r = (polygon / std::f64::consts::PI).sqrt();
    let f = coaxial_disks_factor(r, r, 1.0);
    assert!((f - 0.381897).abs() < 1e-6, "{f}");
}

#[test]
fn closed_cube_is_closed_and_faces_inward() {
    let s = scene("closed_cube");
    assert_eq!(s.mesh.triangles.len(), 6 * 4 * 2);
    let key = |p: DVec3| (p * 1e6).round().to_array().map(|x| x as i64);
    let mut edges: HashMap<([i64; 3], [i64; 3]), usize> = HashMap::new();
    let mut area = 0.0;
    let centre = DVec3::splat(0.5);
    for t in 0..s.mesh.triangles.len() {
        let c = s.mesh.corners(t);
        for i in 0..3 {
            *edges.entry((key(c[i]), key(c[(i + 1) % 3]))).or_default() += 1;
        }
        area += s.mesh.area(t);
        assert!(
            s.mesh.normal(t).dot(centre - s.mesh.centroid(t)) > 0.0,
            "triangle {t} faces outward"
        );
    }
    assert!((area - 6.0).abs() < 1e-12);
    for (&(a, b), &n) in &edges {
        assert_eq!(
            n, 1,
            "edge {a:?} -> {b:?} used {n} times in the same direction"
        );
        assert_eq!(
            edges.get(&(b, a)),
            Some(&1),
            "edge {a:?} -> {b:?} has no opposite edge"
        );
    }
    assert_eq!(s.materials.len(), 1);
    assert_eq!(s.materials[0].kd, [0.5; 3]);
    assert_eq!(s.materials[0].ke, [1.0; 3]);
}

// ---------------------------------------------------------------------------
// Interior

fn degenerate(c: [DVec3; 3]) -> bool {
    let twice = (c[1] - c[0]).cross(c[2] - c[0]).length();
    let longest = (c[1] - c[0])
        .length_squared()
        .max((c[2] - c[1]).length_squared())
        .max((c[0] - c[2]).length_squared());
    let sound = twice > 1e-6 * longest;
    !sound
}

#[test]
fn interior_has_the_thesis_scale_and_valid_geometry() {
    let s = scene("interior");
    let n = s.mesh.triangles.len();
    assert!((50_000..=100_000).contains(&n), "{n} triangles");
    assert_eq!(s.config.units, "m");
    for t in 0..n {
        for &i in &s.mesh.triangles[t] {
            assert!((i as usize) < s.mesh.positions.len());
        }
        assert!(
            !degenerate(s.mesh.corners(t)),
            "triangle {t} is degenerate: {:?}",
            s.mesh.corners(t)
        );
    }
    // Every vertex is used.
    let mut used = vec![false; s.mesh.positions.len()];
    for tri in &s.mesh.triangles {
        for &i in tri {
            used[i as usize] = true;
        }
    }
    assert!(used.iter().all(|&u| u), "unused vertices");
    for m in &s.materials {
        assert!(
            m.kd.iter().all(|&k| (0.0..0.95).contains(&k)),
            "{}: {:?}",
            m.name,
            m.kd
        );
        assert!(m.ke.iter().all(|&k| k >= 0.0));
    }
    let emissive: Vec<&str> = s
        .materials
        .iter()
        .filter(|m| m.ke.iter().any(|&k| k > 0.0))
        .map(|m| m.name.as_str())
        .collect();
    assert_eq!(emissive, ["lamp"]);
    let lamp = s.material_index("lamp").unwrap();
    assert!(
        (s.mesh.material_area(lamp) - 2.0 * 0.36).abs() < 1e-9,
        "two 0.6 m square lamps"
    );
    assert!(s.materials.len() >= 8, "several materials");
    // A building of 18 × 12 m, 7.2 m high at most.
    let (lo, hi) = s.mesh.bounds();
    assert_eq!(lo.to_array(), [0.0, 0.0, 0.0]);
    assert_eq!(hi.to_array(), [18.0, 7.2, 12.0]);
    // No edge longer than a cell's diagonal on the big surfaces: the floors
    // and walls are tessellated (checked on the ceilings' material).
    let ceiling = s.material_index("ceiling").unwrap();
    for t in 0..n {
        if s.mesh.triangle_material[t] == ceiling {
            let c = s.mesh.corners(t);
            for i in 0..3 {
                assert!((c[i] - c[(i + 1) % 3]).length() <= 0.25 * 2f64.sqrt() + 1e-9);
            }
        }
    }
    // The camera stands inside the hall; three lights of the three kinds.
    let cam = s.config.camera.position;
    assert!(
        cam[0] > 0.2
            && cam[0] < 9.9
            && cam[1] > 0.0
            && cam[1] < 7.0
            && cam[2] > 0.2
            && cam[2] < 7.9
    );
    let kinds: Vec<&str> = s
        .config
        .lights
        .iter()
        .map(|l| match l {
            Light::Directional { .. } => "directional",
            Light::Spot { .. } => "spot",
            Light::Point { .. } => "point",
        })
        .collect();
    assert_eq!(kinds, ["directional", "spot", "point"]);
    assert!(s.obj_text().len() < 6_000_000, "OBJ under 6 MB");
}

#[test]
fn interior_is_deterministic() {
    let a = scene("interior");
    let b = scene("interior");
    assert!(a == b);
    assert!(a.obj_text() == b.obj_text());
}

#[test]
fn every_scene_is_valid() {
    for name in BUNDLED {
        let s = scene(name);
        s.config.validate().unwrap();
        assert_eq!(s.mesh.triangles.len(), s.mesh.triangle_material.len());
        // Triangles are grouped by material (one usemtl group each).
        assert!(
            s.mesh.triangle_material.windows(2).all(|w| w[0] <= w[1]),
            "{name}"
        );
        for m in &s.materials {
            assert!(
                m.kd.iter().all(|&k| (0.0..1.0).contains(&k)),
                "{name}/{}",
                m.name
            );
        }
        for t in 0..s.mesh.triangles.len() {
            assert!(!degenerate(s.mesh.corners(t)), "{name}: triangle {t}");
        }
    }
}

// ---------------------------------------------------------------------------
// scene_config

fn sample_config() -> SceneConfig {
    SceneConfig {
        objects: Vec::new(),
        sky: None,
        emission: Default::default(),
        camera: Camera {
            position: [1.0, 2.0, 3.0],
            target: [0.0, 1.0, 0.0],
            up: [0.0, 1.0, 0.0],
            fov_y_deg: 45.0,
        },
        lights: vec![
            Light::Directional {
                direction: [0.3, -1.0, 0.2],
                irradiance: [3.0, 2.5, 2.0],
            },
            Light::Spot {
                position: [0.0, 3.0, 0.0],
                direction: [0.0, -1.0, 0.0],
                intensity: [10.0, 10.0, 9.0],
                cone_angle_deg: 40.0,
                beam_angle_deg: 30.0,
            },
            Light::Point {
                position: [1.0, 1.0, 1.0],
                intensity: [0.5, 0.25, 0.125],
            },
        ],
        units: "m".into(),
        description: "sample".into(),
    }
}

fn parse(text: &str) -> Result<SceneConfig, ConfigError> {
    SceneConfig::from_json(text, Path::new("test.json"))
}

/// The sample as compact JSON with `from` replaced by `to` (exactly once).
fn edited(from: &str, to: &str) -> String {
    let text = serde_json::to_string(&sample_config()).unwrap();
    assert_eq!(text.matches(from).count(), 1, "{from} in {text}");
    text.replace(from, to)
}

fn invalid_field(err: ConfigError) -> (String, String) {
    let msg = err.to_string();
    match err {
        ConfigError::Invalid { invalid, .. } => (invalid.field, msg),
        other => panic!("expected a validation error, got {other}"),
    }
}

#[test]
fn config_round_trips_through_json_and_files() {
    let c = sample_config();
    let text = c.to_json();
    assert!(text.contains("\"type\": \"spot\""), "{text}");
    assert_eq!(parse(&text).unwrap(), c);
    assert_eq!(
        c.to_json(),
        parse(&text).unwrap().to_json(),
        "deterministic text"
    );
    let dir = temp_dir("config");
    let path = dir.join("c.json");
    c.save(&path).unwrap();
    assert_eq!(scene_config::load(&path).unwrap(), c);
    assert_eq!(std::fs::read_to_string(&path).unwrap(), text);
    for name in BUNDLED {
        let s = scene(name);
        let path = dir.join(format!("{name}.json"));
        s.config.save(&path).unwrap();
        assert_eq!(scene_config::load(&path).unwrap(), s.config, "{name}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn config_bad_json_reports_line_and_column() {
    let text = "{\n  \"camera\": {\n    \"position\": [1, 2, 3],\n    \"target\": [0, 0 0],\n";
    let err = parse(text).unwrap_err();
    let msg = err.to_string();
    match err {
        ConfigError::Parse { line, column, .. } => {
            assert_eq!(line, 4, "{msg}");
            assert!(column > 0);
        }
        other => panic!("expected a parse error, got {other}"),
    }
    assert!(msg.starts_with("test.json:4:"), "{msg}");
}

#[test]
fn config_rejects_unknown_fields() {
    let err = parse(&edited("\"fov_y_deg\"", "\"fov\"")).unwrap_err();
    let msg = err.to_string();
    assert!(matches!(err, ConfigError::Parse { .. }), "{msg}");
    assert!(
        msg.contains("unknown field") && msg.contains("fov"),
        "{msg}"
    );
    let err = parse(&edited("\"beam_angle_deg\"", "\"penumbra_deg\"")).unwrap_err();
    assert!(err.to_string().contains("penumbra_deg"), "{err}");
    let err = parse(&edited("\"description\"", "\"comment\":1,\"description\"")).unwrap_err();
    assert!(err.to_string().contains("comment"), "{err}");
    let err = parse(&edited("\"point\"", "\"area\"")).unwrap_err();
    assert!(err.to_string().contains("area"), "{err}");
}

#[test]
fn config_rejects_zero_directions() {
    let mut c = sample_config();
    c.lights[0] = Light::Directional {
        direction: [0.0, 0.0, 0.0],
        irradiance: [1.0; 3],
    };
    let err = parse(&c.to_json()).unwrap_err();
    let (field, msg) = invalid_field(err);
    assert_eq!(field, "lights[0].direction");
    assert!(
        msg.contains("test.json") && msg.contains("[0, 0, 0]") && msg.contains("non-zero"),
        "{msg}"
    );
    let mut c = sample_config();
    c.camera.up = [0.0; 3];
    assert_eq!(
        invalid_field(parse(&c.to_json()).unwrap_err()).0,
        "camera.up"
    );
    let mut c = sample_config();
    c.camera.up = [-1.0, -1.0, -3.0]; // parallel to the view direction
    assert_eq!(
        invalid_field(parse(&c.to_json()).unwrap_err()).0,
        "camera.up"
    );
    let mut c = sample_config();
    c.camera.target = c.camera.position;
    assert_eq!(
        invalid_field(parse(&c.to_json()).unwrap_err()).0,
        "camera.target"
    );
}

/// Valid at any scale: a scene far out or tiny (camera and target), an up vector or light directions
/// with tiny or huge components (their squared lengths leave f32's range;
/// the check of a parallel up vector once overflowed and named the up
/// vector of a camera at 1e30).
#[test]
fn config_accepts_directions_and_positions_at_any_scale() {
    for s in [1e-30f32, 1e30] {
        let mut c = sample_config();
        c.camera.position = c.camera.position.map(|v| v * s);
        c.camera.target = c.camera.target.map(|v| v * s);
        c.camera.up = c.camera.up.map(|v| v * s);
        for l in &mut c.lights {
            if let Light::Directional { direction, .. } | Light::Spot { direction, .. } = l {
                *direction = direction.map(|v| v * s);
            }
        }
        c.validate().unwrap_or_else(|e| panic!("scale {s}: {e}"));
        // A parallel up vector is still refused at that scale.
        let view: [f32; 3] = std::array::from_fn(|k| c.camera.target[k] - c.camera.position[k]);
        c.camera.up = view.map(|v| v * 1e-3);
        assert_eq!(c.validate().unwrap_err().field, "camera.up", "scale {s}");
    }
}

#[test]
fn config_rejects_non_finite_values() {
    // JSON has no NaN: the parser rejects it with its position.
    let err = parse(&edited("\"fov_y_deg\":45.0", "\"fov_y_deg\":NaN")).unwrap_err();
    assert!(matches!(err, ConfigError::Parse { .. }), "{err}");
    // A number too large for f32 becomes infinite and is caught.
    let (field, msg) =
        invalid_field(parse(&edited("\"fov_y_deg\":45.0", "\"fov_y_deg\":1e39")).unwrap_err());
    assert_eq!(field, "camera.fov_y_deg", "{msg}");
    let (field, msg) =
        invalid_field(parse(&edited("[1.0,2.0,3.0]", "[1.0,2.0,1e40]")).unwrap_err());
    assert_eq!(field, "camera.position");
    assert!(msg.contains("finite"), "{msg}");
    // In memory, NaN is caught by validate and by save.
    let mut c = sample_config();
    c.lights[2] = Light::Point {
        position: [f32::NAN, 0.0, 0.0],
        intensity: [1.0; 3],
    };
    let err = c.validate().unwrap_err();
    assert_eq!(err.field, "lights[2].position");
    assert!(err.to_string().contains("NaN"), "{err}");
    let dir = temp_dir("nan");
    let path = dir.join("nan.json");
    let (_, msg) = invalid_field(c.save(&path).unwrap_err());
    assert!(msg.contains("nan.json"), "{msg}");
    assert!(
        !path.exists(),
        "nothing written for an invalid configuration"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn config_rejects_negative_intensity() {
    let (field, msg) =
        invalid_field(parse(&edited("[0.5,0.25,0.125]", "[0.5,-0.25,0.125]")).unwrap_err());
    assert_eq!(field, "lights[2].intensity");
    assert!(
        msg.contains("-0.25") && msg.contains("non-negative"),
        "{msg}"
    );
    let (field, _) = invalid_field(parse(&edited("[3.0,2.5,2.0]", "[3.0,-2.5,2.0]")).unwrap_err());
    assert_eq!(field, "lights[0].irradiance");
    let (field, _) =
        invalid_field(parse(&edited("[10.0,10.0,9.0]", "[-10.0,10.0,9.0]")).unwrap_err());
    assert_eq!(field, "lights[1].intensity");
}

#[test]
fn config_rejects_angles_out_of_range() {
    for fov in ["0.0", "-10.0", "180.0", "200.0"] {
        let (field, msg) = invalid_field(
            parse(&edited(
                "\"fov_y_deg\":45.0",
                &format!("\"fov_y_deg\":{fov}"),
            ))
            .unwrap_err(),
        );
        assert_eq!(field, "camera.fov_y_deg", "{msg}");
        assert!(msg.contains("(0, 180)"), "{msg}");
    }
    assert!(parse(&edited("\"fov_y_deg\":45.0", "\"fov_y_deg\":179.0")).is_ok());
    for cone in ["0.0", "90.5"] {
        let text = edited(
            "\"cone_angle_deg\":40.0",
            &format!("\"cone_angle_deg\":{cone}"),
        );
        let (field, _) = invalid_field(parse(&text).unwrap_err());
        assert_eq!(field, "lights[1].cone_angle_deg");
    }
    let text = edited("\"cone_angle_deg\":40.0", "\"cone_angle_deg\":90.0");
    assert!(parse(&text).is_ok(), "a 90 degree cone is allowed");
    let (field, _) = invalid_field(
        parse(&edited(
            "\"beam_angle_deg\":30.0",
            "\"beam_angle_deg\":41.0",
        ))
        .unwrap_err(),
    );
    assert_eq!(field, "lights[1].beam_angle_deg");
    let (field, _) =
        invalid_field(parse(&edited("\"units\":\"m\"", "\"units\":\"\"")).unwrap_err());
    assert_eq!(field, "units");
}

#[test]
fn config_missing_file_names_the_path() {
    let err = scene_config::load(Path::new("/nonexistent/scene.json")).unwrap_err();
    assert!(matches!(err, ConfigError::Io { .. }));
    assert!(err.to_string().contains("/nonexistent/scene.json"), "{err}");
}
