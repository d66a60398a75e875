//! Integration tests of the scene loader: one test per kind of bad input
//! (each checks the error kind and that the message names the file and the
//! line or value), the repairs, texture averaging, Sponza, and a fuzz-style
//! property test that `load` never panics.

use proptest::prelude::*;
use radiosity::core::error::SceneError;
use radiosity::core::scene::{self, Scene, ALBEDO_MAX, DEFAULT_ALBEDO};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// A fresh, empty directory under the system temp dir, removed on drop.
struct Scratch(PathBuf);

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A fresh, empty directory, unique per call.
fn temp_dir(name: &str) -> Scratch {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!(
        "radiosity-scene-load-{}-{name}-{n}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    Scratch(dir)
}

/// Writes `files` (name, contents) into a fresh directory; returns the
/// directory (keep it alive) and the path of the first file.
fn write_files(test: &str, files: &[(&str, &str)]) -> (Scratch, PathBuf) {
    let dir = temp_dir(test);
    for (name, contents) in files {
        std::fs::write(dir.join(name), contents).unwrap();
    }
    let first = dir.join(files[0].0);
    (dir, first)
}

/// Loads and expects a `Parse` error; returns (file, line, Display text).
fn expect_parse_error(path: &Path) -> (PathBuf, usize, String) {
    match scene::load(path) {
        Err(e @ SceneError::Parse { .. }) => {
            let text = e.to_string();
            let SceneError::Parse { path, line, .. } = e else {
                unreachable!()
            };
            (path, line, text)
        }
        Err(e) => panic!("expected a parse error, got {e:?}"),
        Ok(_) => panic!("expected a parse error, the scene loaded"),
    }
}

/// Asserts a `Parse` error at `line` of `path` whose text names the file,
/// the line and contains `needle`.
fn assert_parse_error_at(path: &Path, line: usize, needle: &str) {
    let (file, at, text) = expect_parse_error(path);
    assert_eq!(file, path, "{text}");
    assert_eq!(at, line, "{text}");
    let name = path.file_name().unwrap().to_str().unwrap();
    assert!(
        text.contains(name),
        "message does not name the file: {text}"
    );
    assert!(
        text.contains(&format!(":{line}:")),
        "message does not name line {line}: {text}"
    );
    assert!(text.contains(needle), "message lacks `{needle}`: {text}");
}

const QUAD: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n";

fn material_named<'a>(scene: &'a Scene, name: &str) -> &'a scene::Material {
    scene
        .materials
        .iter()
        .find(|m| m.name == name)
        .unwrap_or_else(|| panic!("no material {name} in {:?}", scene.materials))
}

#[test]
fn missing_obj_file_is_an_io_error_naming_the_path() {
    let path = temp_dir("missing-obj").join("nowhere.obj");
    let err = scene::load(&path).unwrap_err();
    assert!(matches!(err, SceneError::Io { .. }), "{err:?}");
    assert!(err.to_string().contains("nowhere.obj"), "{err}");
}

#[test]
fn missing_mtl_warns_and_uses_the_default_albedo() {
    let obj = format!("mtllib gone.mtl\nusemtl red\n{QUAD}");
    let (_dir, path) = write_files("missing-mtl", &[("scene.obj", &obj)]);
    let scene = scene::load(&path).unwrap();
    assert_eq!(scene.triangle_count(), 2);
    assert!(
        scene.warnings.iter().any(|w| w.contains("gone.mtl")),
        "{:?}",
        scene.warnings
    );
    assert_eq!(scene.repairs.missing_materials, 1);
    assert_eq!(scene.materials.len(), 1);
    assert_eq!(scene.materials[0].albedo, [DEFAULT_ALBEDO; 3]);
}

#[test]
fn undefined_material_warns_and_is_counted_once() {
    let mtl = "newmtl red\nKd 0.5 0.1 0.1\n";
    let obj =
        format!("mtllib m.mtl\nusemtl blue\n{QUAD}usemtl blue\nf 1 2 4\nusemtl red\nf 2 3 4\n");
    let (_dir, path) = write_files("undefined-material", &[("scene.obj", &obj), ("m.mtl", mtl)]);
    let scene = scene::load(&path).unwrap();
    assert_eq!(scene.repairs.missing_materials, 1);
    assert!(
        scene.warnings.iter().any(|w| w.contains("`blue` (line 2)")),
        "{:?}",
        scene.warnings
    );
    assert_eq!(scene.materials.len(), 2, "red and the default");
    assert_eq!(material_named(&scene, "red").albedo, [0.5, 0.1, 0.1]);
    assert_eq!(
        material_named(&scene, "(default)").albedo,
        [DEFAULT_ALBEDO; 3]
    );
}

/// A room 3.3 × 2.7 × 4.1 m with a table top 4 cm thick, written at
/// survey coordinates (5.4e6 m north, where `f32` spacing is 0.5 m): the
/// loader warns that storing its coordinates distorts it, naming the
/// largest change, its line and the remedy. The same room near the origin
/// and 1 km from it (spacing 61 µm, 1.5e-5 of its extent) does not warn.
#[test]
fn coordinates_that_f32_distorts_are_a_warning() {
    let room = |o: [f64; 3]| -> String {
        let mut v = Vec::new();
        for &(x, y, z) in &[
            (0.0, 0.0, 0.0),
            (3.3, 0.0, 0.0),
            (3.3, 2.7, 0.0),
            (0.0, 2.7, 0.0),
            (0.0, 0.0, 4.1),
            (3.3, 0.0, 4.1),
            (3.3, 2.7, 4.1),
            (0.0, 2.7, 4.1),
            (1.2, 0.70, 1.5),
            (2.0, 0.70, 1.5),
            (2.0, 0.74, 2.3),
            (1.2, 0.74, 2.3),
        ] {
            v.push(format!(
                "v {:.4} {:.4} {:.4}\n",
                x + o[0],
                y + o[1],
                z + o[2]
            ));
        }
        v.concat()
            + "f 1 2 3 4\nf 5 8 7 6\nf 1 5 6 2\nf 4 3 7 8\nf 1 4 8 5\nf 2 6 7 3\nf 9 10 11 12\n"
    };
    let survey = room([512_345.0, 87.0, 5_412_345.0]);
    let (_d1, p1) = write_files("survey", &[("scene.obj", &survey)]);
    let scene = scene::load(&p1).unwrap();
    let w = scene
        .warnings
        .iter()
        .find(|w| w.contains("32-bit floats"))
        .unwrap_or_else(|| panic!("no precision warning: {:?}", scene.warnings));
    // The table's far edge, z = 5412347.3, is stored as 5412347.5 (line
    // 11); the walls' 5412349.1 as 5412349.0, a smaller change.
    assert!(
        w.contains("scene.obj") && w.contains("line 11") && w.contains("near the origin"),
        "{w}"
    );
    assert!(w.contains("change by up to 2.000e-1"), "{w}");
    for (tag, o) in [("local", [0.0; 3]), ("km", [1000.0, 0.0, -1000.0])] {
        let (_d, p) = write_files(tag, &[("scene.obj", &room(o))]);
        let scene = scene::load(&p).unwrap();
        assert!(
            !scene.warnings.iter().any(|w| w.contains("32-bit")),
            "{tag}: {:?}",
            scene.warnings
        );
    }
}

/// Polygon faces that are not convex (a C-shaped floor, an L-shaped wall
/// with its notch at the first vertex) are cut into triangles that cover
/// exactly their area, all wound like the face; tobj's fan gave the C an
/// area of 11 instead of 7, with triangles wound backwards. Convex quads
/// keep the fan.
#[test]
fn nonconvex_polygons_are_cut_into_their_own_area() {
    // The C opens towards +x, in the floor plane, facing +y; then an L in
    // the plane z = 0 facing +z whose first vertex is the reflex corner
    // (a fan from it leaves the polygon); then a convex quad.
    let obj = "v 0 0 0\nv 0 0 -3\nv 3 0 -3\nv 3 0 -2\nv 1 0 -2\nv 1 0 -1\nv 3 0 -1\nv 3 0 0\n\
               f 1 8 7 6 5 4 3 2\n\
               v 1 1 0\nv 1 3 0\nv 0 3 0\nv 0 0 0.0\nv 3 0 0.0\nv 3 1 0\n\
               f 9 10 11 12 13 14\n\
               v 5 0 0\nv 6 0 0\nv 6 0 -1\nv 5 0 -1\nf 15 16 17 18\n";
    let (_dir, path) = write_files("nonconvex", &[("scene.obj", obj)]);
    let scene = scene::load(&path).unwrap();
    assert_eq!(scene.repairs.nonconvex_polygons, 2);
    assert_eq!(scene.repairs.untriangulated_polygons, 0);
    assert_eq!(scene.triangle_count(), 6 + 4 + 2);
    let sum = |r: std::ops::Range<usize>| -> f64 { r.map(|t| scene.triangle_area(t)).sum() };
    assert!((sum(0..6) - 7.0).abs() < 1e-6, "C area {}", sum(0..6));
    assert!((sum(6..10) - 5.0).abs() < 1e-6, "L area {}", sum(6..10));
    assert!(
        (sum(10..12) - 1.0).abs() < 1e-6,
        "quad area {}",
        sum(10..12)
    );
    for (range, n) in [
        (0..6, [0.0, 1.0, 0.0]),
        (6..10, [0.0, 0.0, 1.0]),
        (10..12, [0.0, 1.0, 0.0]),
    ] {
        for t in range {
            let m = scene.triangle_normal(t);
            assert!(
                (m[0] * n[0] + m[1] * n[1] + m[2] * n[2] - 1.0).abs() < 1e-9,
                "triangle {t} faces {m:?}, not {n:?}"
            );
        }
    }
    // The convex quad is the fan, as tobj made it.
    let q = scene.triangles[10];
    let p = |i: u32| scene.positions[i as usize];
    assert_eq!(
        (p(q[0]), p(q[1]), p(q[2])),
        ([5.0, 0.0, 0.0], [6.0, 0.0, 0.0], [6.0, 0.0, -1.0])
    );
}

#[test]
fn triangles_without_material_get_the_default_without_counting() {
    let (_dir, path) = write_files("no-material", &[("scene.obj", QUAD)]);
    let scene = scene::load(&path).unwrap();
    assert_eq!(scene.repairs, scene::Repairs::default());
    assert_eq!(scene.materials.len(), 1);
    assert_eq!(scene.materials[0].albedo, [DEFAULT_ALBEDO; 3]);
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
}

#[test]
fn missing_texture_warns_and_uses_kd_alone() {
    let mtl = "newmtl wall\nKd 0.5 0.25 0.125\nmap_Kd textures/absent.png\n";
    let obj = format!("mtllib m.mtl\nusemtl wall\n{QUAD}");
    let (_dir, path) = write_files("missing-texture", &[("scene.obj", &obj), ("m.mtl", mtl)]);
    let scene = scene::load(&path).unwrap();
    assert!(
        scene.warnings.iter().any(|w| w.contains("absent.png")),
        "{:?}",
        scene.warnings
    );
    assert_eq!(scene.repairs.missing_textures, 1);
    let wall = material_named(&scene, "wall");
    assert_eq!(wall.albedo, [0.5, 0.25, 0.125]);
    assert!(wall.diffuse_texture.is_none());
}

#[test]
fn undecodable_texture_warns_and_uses_kd_alone() {
    let mtl = "newmtl wall\nKd 0.5 0.5 0.5\nmap_Kd broken.png\n";
    let obj = format!("mtllib m.mtl\nusemtl wall\n{QUAD}");
    let (_dir, path) = write_files(
        "broken-texture",
        &[
            ("scene.obj", &obj),
            ("m.mtl", mtl),
            ("broken.png", "not a png"),
        ],
    );
    let scene = scene::load(&path).unwrap();
    assert!(
        scene.warnings.iter().any(|w| w.contains("broken.png")),
        "{:?}",
        scene.warnings
    );
    assert_eq!(scene.repairs.missing_textures, 1);
    assert_eq!(material_named(&scene, "wall").albedo, [0.5; 3]);
}

#[test]
fn nan_coordinate_names_the_line() {
    let obj = "# a comment\nv 0 0 0\nv 1 0 0\nv 1 nan 0\nf 1 2 3\n";
    let (_dir, path) = write_files("nan", &[("scene.obj", obj)]);
    assert_parse_error_at(&path, 4, "NaN");
}

#[test]
fn infinite_coordinate_names_the_line() {
    assert!(
        "1e39".parse::<f32>().unwrap().is_infinite(),
        "1e39 overflows f32"
    );
    let obj = "v 0 0 0\nv 1 0 0\nv 1 1 1e39\nf 1 2 3\n";
    let (_dir, path) = write_files("inf", &[("scene.obj", obj)]);
    assert_parse_error_at(&path, 3, "inf");
}

#[test]
fn huge_coordinate_names_the_line_and_value() {
    let obj = "v 0 0 0\nv 1e9 0 0\nv 1 1 0\nf 1 2 3\n";
    let (_dir, path) = write_files("huge", &[("scene.obj", obj)]);
    assert_parse_error_at(&path, 2, "1000000000");
}

#[test]
fn huge_coordinate_through_w_division_names_the_line() {
    let obj = "v 0 0 0\nv 1 0 0\nv 1 1 0 1e-9\nf 1 2 3\n";
    let (_dir, path) = write_files("huge-w", &[("scene.obj", obj)]);
    assert_parse_error_at(&path, 3, "v 1 1 0 1e-9");
}

#[test]
fn face_index_out_of_range_names_the_face_line() {
    // The error surfaces in tobj only at the end of the group (line 8);
    // the second scan must point at the face on line 5.
    let obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\nf 1 2 9\nf 1 3 2\no next\nv 0 0 1\n";
    let (_dir, path) = write_files("index-range", &[("scene.obj", obj)]);
    assert_parse_error_at(&path, 5, "f 1 2 9");
}

#[test]
fn relative_face_index_out_of_range_names_the_face_line() {
    let obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nf -1 -2 -4\n";
    let (_dir, path) = write_files("relative-range", &[("scene.obj", obj)]);
    assert_parse_error_at(&path, 4, "-4");
}

#[test]
fn texcoord_index_that_would_overflow_tobj_is_an_error_not_a_panic() {
    let obj =
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf 1/-3 2/1 3/1\nf 1/9223372036854775807 2/1 3/1\n";
    let (_dir, path) = write_files("texcoord-overflow", &[("scene.obj", obj)]);
    assert_parse_error_at(&path, 5, "texture coordinate");
    let obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf 1/9223372036854775807 2/1 3/1\n";
    let (_dir, path) = write_files("texcoord-overflow-2", &[("scene.obj", obj)]);
    assert_parse_error_at(&path, 5, "out of range");
}

#[test]
fn face_index_zero_names_the_face_line() {
    let obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 0 1 2\n";
    let (_dir, path) = write_files("index-zero", &[("scene.obj", obj)]);
    assert_parse_error_at(&path, 4, "index 0");
}

#[test]
fn malformed_vertex_line_names_the_line() {
    let obj = "v 0 0 0\nv 1.0 abc 2.0\nv 1 1 0\nf 1 2 3\n";
    let (_dir, path) = write_files("malformed-v", &[("scene.obj", obj)]);
    assert_parse_error_at(&path, 2, "v 1.0 abc 2.0");
}

#[test]
fn malformed_face_line_names_the_line() {
    let obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 x 3\n";
    let (_dir, path) = write_files("malformed-f", &[("scene.obj", obj)]);
    assert_parse_error_at(&path, 4, "f 1 x 3");
}

#[test]
fn invalid_utf8_lines_are_decoded_lossily_with_a_warning() {
    let dir = temp_dir("utf8");
    let path = dir.join("scene.obj");
    let mut bytes = b"# caf\xe9\n".to_vec();
    bytes.extend_from_slice(QUAD.as_bytes());
    std::fs::write(&path, bytes).unwrap();
    let scene = scene::load(&path).unwrap();
    assert_eq!(scene.triangle_count(), 2);
    assert!(
        scene.warnings.iter().any(|w| w.contains("UTF-8")),
        "{:?}",
        scene.warnings
    );
}

#[test]
fn byte_order_mark_does_not_hide_the_first_record() {
    let (_dir, path) = write_files("bom", &[("scene.obj", &format!("\u{feff}{QUAD}"))]);
    let scene = scene::load(&path).unwrap();
    assert_eq!(scene.positions.len(), 4);
    assert_eq!(scene.triangle_count(), 2);
}

#[test]
fn degenerate_triangles_are_skipped_and_counted() {
    let obj = format!(
        "{QUAD}f 1 1 2\nv 2 0 0\nf 1 2 5\nf 1 2\n" // repeated index, collinear, a line
    );
    let (_dir, path) = write_files("degenerate", &[("scene.obj", &obj)]);
    let scene = scene::load(&path).unwrap();
    assert_eq!(scene.triangle_count(), 2);
    assert_eq!(scene.repairs.degenerate_triangles, 3);
    assert_eq!(
        scene.positions.len(),
        4,
        "vertices used only by skipped triangles are dropped"
    );
    assert!((scene.surface_area() - 1.0).abs() < 1e-12);
    assert!(scene.warnings.iter().any(|w| w.contains("degenerate")));
}

#[test]
fn tiny_but_well_shaped_triangles_are_kept() {
    let obj = "v 0 0 0\nv 1e-6 0 0\nv 0 1e-6 0\nf 1 2 3\n";
    let (_dir, path) = write_files("tiny", &[("scene.obj", obj)]);
    let scene = scene::load(&path).unwrap();
    assert_eq!(scene.triangle_count(), 1);
    assert_eq!(scene.repairs.degenerate_triangles, 0);
}

#[test]
fn albedo_at_or_above_one_is_clamped_and_counted_per_component() {
    let mtl = "newmtl bright\nKd 1.5 0.5 1.0\n";
    let obj = format!("mtllib m.mtl\nusemtl bright\n{QUAD}");
    let (_dir, path) = write_files("clamp", &[("scene.obj", &obj), ("m.mtl", mtl)]);
    let scene = scene::load(&path).unwrap();
    let m = material_named(&scene, "bright");
    assert_eq!(m.albedo, [ALBEDO_MAX, 0.5, ALBEDO_MAX]);
    assert_eq!(m.kd, [1.5, 0.5, 1.0], "Kd is kept as written");
    assert_eq!(scene.repairs.clamped_albedo_components, 2);
}

#[test]
fn negative_kd_is_an_error_naming_material_and_mtl_file() {
    let mtl = "newmtl good\nKd 0.5 0.5 0.5\n\nnewmtl bad_paint\nKd 0.5 -0.1 0.5\n";
    let obj = format!("mtllib paints.mtl\nusemtl bad_paint\n{QUAD}");
    let (_dir, path) = write_files("negative-kd", &[("scene.obj", &obj), ("paints.mtl", mtl)]);
    let err = scene::load(&path).unwrap_err();
    let text = err.to_string();
    assert!(matches!(err, SceneError::Parse { line: 5, .. }), "{err:?}");
    assert!(text.contains("paints.mtl:5:"), "{text}");
    assert!(text.contains("bad_paint"), "{text}");
}

#[test]
fn non_finite_ke_is_an_error_naming_material_and_mtl_file() {
    let mtl = "newmtl lamp\nKd 0.5 0.5 0.5\nKe nan 1 1\n";
    let obj = format!("mtllib lamps.mtl\nusemtl lamp\n{QUAD}");
    let (_dir, path) = write_files("nan-ke", &[("scene.obj", &obj), ("lamps.mtl", mtl)]);
    let text = scene::load(&path).unwrap_err().to_string();
    assert!(text.contains("lamps.mtl:3:"), "{text}");
    assert!(text.contains("lamp"), "{text}");
}

#[test]
fn short_colour_records_are_errors_or_expanded_not_panics() {
    // tobj panics on `Kd` with fewer than three numbers; two is an error,
    // one is the MTL spec's grey shorthand.
    let obj = format!("mtllib m.mtl\nusemtl a\n{QUAD}");
    let (_dir, path) = write_files(
        "short-kd",
        &[("scene.obj", &obj), ("m.mtl", "newmtl a\nKd 0.5 0.5\n")],
    );
    let text = scene::load(&path).unwrap_err().to_string();
    assert!(text.contains("m.mtl:2:"), "{text}");
    let (_dir, path) = write_files(
        "grey-kd",
        &[("scene.obj", &obj), ("m.mtl", "newmtl a\nKd 0.25\n")],
    );
    let scene = scene::load(&path).unwrap();
    assert_eq!(material_named(&scene, "a").albedo, [0.25; 3]);
}

#[test]
fn malformed_mtl_record_names_the_mtl_line() {
    let obj = format!("mtllib m.mtl\nusemtl a\n{QUAD}");
    let mtl = "newmtl a\nKd 0.5 0.5 0.5\nNs shiny\n";
    let (_dir, path) = write_files("bad-mtl", &[("scene.obj", &obj), ("m.mtl", mtl)]);
    let text = scene::load(&path).unwrap_err().to_string();
    assert!(text.contains("m.mtl:3:"), "{text}");
}

#[test]
fn emission_comes_from_ke() {
    let mtl = "newmtl lamp\nKd 0.5 0.5 0.5\nKe 10 9 8\n\nnewmtl wall\nKd 0.5 0.5 0.5\n";
    let obj = "mtllib m.mtl\nv 0 0 0\nv 2 0 0\nv 2 1 0\nv 0 1 0\nusemtl lamp\nf 1 2 3\nusemtl wall\nf 1 3 4\n";
    let (_dir, path) = write_files("emission", &[("scene.obj", obj), ("m.mtl", mtl)]);
    let scene = scene::load(&path).unwrap();
    assert_eq!(material_named(&scene, "lamp").emission, [10.0, 9.0, 8.0]);
    assert_eq!(material_named(&scene, "wall").emission, [0.0; 3]);
    assert!((scene.emissive_area() - 1.0).abs() < 1e-12);
    assert!((scene.surface_area() - 2.0).abs() < 1e-12);
}

#[test]
fn empty_scene_with_only_vertices_is_empty() {
    let (_dir, path) = write_files(
        "empty-vertices",
        &[("scene.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\n")],
    );
    let err = scene::load(&path).unwrap_err();
    assert!(matches!(err, SceneError::Empty { .. }), "{err:?}");
    assert!(err.to_string().contains("scene.obj"), "{err}");
}

#[test]
fn empty_scene_with_only_degenerate_faces_is_empty() {
    let obj = "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 1 1 2\n";
    let (_dir, path) = write_files("empty-degenerate", &[("scene.obj", obj)]);
    let err = scene::load(&path).unwrap_err();
    assert!(matches!(err, SceneError::Empty { .. }), "{err:?}");
    let text = err.to_string();
    assert!(
        text.contains("scene.obj") && text.contains("degenerate"),
        "{text}"
    );
}

#[test]
fn winding_against_vertex_normals_is_counted_not_flipped() {
    let obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nvn 0 0 -1\n\
               f 1//1 2//1 3//1\nf 1//2 3//2 4//2\n";
    let (_dir, path) = write_files("winding", &[("scene.obj", obj)]);
    let scene = scene::load(&path).unwrap();
    assert_eq!(scene.repairs.winding_disagrees_with_normals, 1);
    assert_eq!(
        scene.triangle_normal(1),
        [0.0, 0.0, 1.0],
        "geometry is kept"
    );
    assert_eq!(scene.normals.len(), scene.positions.len());
}

#[test]
fn partial_normals_and_texcoords_are_filled() {
    let obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 5 5 5\nv 6 5 5\nv 6 6 5\n\
               vt 0.5 0.5\nvn 0 0 1\n\
               o a\nf 1/1/1 2/1/1 3/1/1\nf 1/1/1 3/1/1 4/1/1\n\
               o b\nf 5 6 7\n";
    let (_dir, path) = write_files("partial", &[("scene.obj", obj)]);
    let scene = scene::load(&path).unwrap();
    assert_eq!(scene.normals.len(), scene.positions.len());
    assert_eq!(scene.texcoords.len(), scene.positions.len());
    for n in &scene.normals {
        assert_eq!(*n, [0.0, 0.0, 1.0]);
    }
    assert!(scene.texcoords.contains(&[0.0, 0.0]) && scene.texcoords.contains(&[0.5, 0.5]));
    assert!(
        scene.warnings.iter().any(|w| w.contains("normal")),
        "{:?}",
        scene.warnings
    );
}

/// The linear mean of `values` as the test computes it, independently.
fn expected_linear_mean(values: &[[u8; 3]]) -> [f64; 3] {
    let eotf = |c: u8| {
        let c = c as f64 / 255.0;
        if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }
    };
    let mut sum = [0.0; 3];
    for v in values {
        for k in 0..3 {
            sum[k] += eotf(v[k]);
        }
    }
    sum.map(|s| s / values.len() as f64)
}

#[test]
fn texture_average_is_linear_mean_times_kd() {
    let dir = temp_dir("texture-average");
    let pixels: [[u8; 3]; 6] = [
        [0, 0, 0],
        [255, 255, 255],
        [128, 64, 10],
        [10, 200, 30],
        [250, 1, 100],
        [90, 90, 180],
    ];
    let mut image = image::RgbImage::new(3, 2);
    for (i, p) in pixels.iter().enumerate() {
        image.put_pixel(i as u32 % 3, i as u32 / 3, image::Rgb(*p));
    }
    std::fs::create_dir_all(dir.join("tex")).unwrap();
    image.save(dir.join("tex/checker.png")).unwrap();
    let kd = [0.9f32, 0.5, 0.25];
    // The MTL lives in a subdirectory: the texture resolves relative to it.
    std::fs::create_dir_all(dir.join("mtl")).unwrap();
    std::fs::write(
        dir.join("mtl/m.mtl"),
        format!(
            "newmtl tex\nKd {} {} {}\nmap_Kd ../tex/checker.png\n",
            kd[0], kd[1], kd[2]
        ),
    )
    .unwrap();
    let path = dir.join("scene.obj");
    std::fs::write(&path, format!("mtllib mtl/m.mtl\nusemtl tex\n{QUAD}")).unwrap();
    let scene = scene::load(&path).unwrap();
    let m = material_named(&scene, "tex");
    let mean = expected_linear_mean(&pixels);
    for k in 0..3 {
        let expected = kd[k] as f64 * mean[k];
        assert!(
            (m.albedo[k] as f64 - expected).abs() < 1e-6,
            "channel {k}: {} vs {expected}",
            m.albedo[k]
        );
    }
    assert!(m
        .diffuse_texture
        .as_ref()
        .and_then(|t| t.path())
        .unwrap()
        .ends_with("tex/checker.png"));
    assert_eq!(scene.repairs.missing_textures, 0);
}

#[test]
fn grey_texture_counts_as_equal_channels() {
    let dir = temp_dir("grey-texture");
    let image = image::GrayImage::from_raw(2, 1, vec![0, 200]).unwrap();
    image.save(dir.join("g.png")).unwrap();
    std::fs::write(dir.join("m.mtl"), "newmtl g\nmap_Kd g.png\n").unwrap();
    let path = dir.join("scene.obj");
    std::fs::write(&path, format!("mtllib m.mtl\nusemtl g\n{QUAD}")).unwrap();
    let scene = scene::load(&path).unwrap();
    let expected = expected_linear_mean(&[[0; 3], [200; 3]])[0];
    let m = material_named(&scene, "g");
    assert_eq!(
        m.kd, [1.0; 3],
        "no Kd with a texture means the texture alone"
    );
    for c in m.albedo {
        assert!((c as f64 - expected).abs() < 1e-6);
    }
}

#[test]
fn summary_has_the_documented_keys_and_a_text_form() {
    let mtl = "newmtl lamp\nKd 0.5 0.5 0.5\nKe 1 1 1\n";
    let obj = format!("mtllib m.mtl\nusemtl lamp\n{QUAD}f 1 1 2\n");
    let (_dir, path) = write_files("summary", &[("scene.obj", &obj), ("m.mtl", mtl)]);
    let scene = scene::load(&path).unwrap();
    let summary = scene.summary();
    let json = serde_json::to_value(&summary).unwrap();
    for key in [
        "triangles",
        "vertices",
        "materials",
        "bounds",
        "area",
        "emissive_area",
        "repairs",
        "warnings",
    ] {
        assert!(json.get(key).is_some(), "missing key {key} in {json}");
    }
    assert_eq!(json["triangles"], 2);
    assert_eq!(json["bounds"]["min"], serde_json::json!([0.0, 0.0, 0.0]));
    assert_eq!(json["bounds"]["max"], serde_json::json!([1.0, 1.0, 0.0]));
    assert_eq!(json["repairs"]["degenerate_triangles"], 1);
    assert_eq!(json["area"], 1.0);
    assert_eq!(json["emissive_area"], 1.0);
    let text = summary.to_string();
    assert!(text.lines().count() >= 8, "{text}");
    assert!(
        text.contains("triangles") && text.contains("degenerate"),
        "{text}"
    );
}

#[test]
fn sponza_loads_with_its_counts_bounds_and_textures() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes/sponza/sponza.obj");
    assert!(
        path.exists(),
        "Sponza is missing at {}: the scene corpus must be present for this test",
        path.display()
    );
    let start = std::time::Instant::now();
    let scene = scene::load(&path).unwrap();
    let seconds = start.elapsed().as_secs_f64();
    println!(
        "Sponza: {} triangles, {} vertices, {} materials, loaded in {seconds:.3} s",
        scene.triangle_count(),
        scene.positions.len(),
        scene.materials.len()
    );
    println!("{}", scene.summary());
    assert_eq!(scene.triangle_count(), 66_445);
    assert_eq!(scene.repairs, scene::Repairs::default());
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    // The MTL defines 20 materials; the OBJ uses 19 of them.
    assert_eq!(scene.materials.len(), 19);
    assert!(scene.normals.is_empty(), "the file has no normals");
    assert_eq!(scene.texcoords.len(), scene.positions.len());
    let (lo, hi) = scene.bounds();
    let (want_lo, want_hi) = ([-17.4f32, -0.9, -7.8], [17.4f32, 15.7, 7.8]);
    for k in 0..3 {
        assert!(lo[k].is_finite() && hi[k].is_finite());
        assert!((lo[k] - want_lo[k]).abs() < 0.2, "min {lo:?}");
        assert!((hi[k] - want_hi[k]).abs() < 0.2, "max {hi:?}");
    }
    for m in &scene.materials {
        for c in m.albedo {
            assert!(
                (0.0..=ALBEDO_MAX).contains(&c),
                "{}: {:?}",
                m.name,
                m.albedo
            );
        }
    }
    let textured = scene
        .materials
        .iter()
        .filter(|m| m.diffuse_texture.is_some())
        .count();
    assert!(
        textured >= 18,
        "only {textured} materials found their texture"
    );
    assert!(seconds < 20.0, "Sponza took {seconds:.1} s to load");
}

/// A small valid scene with texcoords, normals, groups and materials, for
/// the mutation fuzzing.
const FUZZ_OBJ: &str = "mtllib m.mtl
o box
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
vt 0 0
vt 1 0
vt 1 1
vn 0 0 1
vn 0 1 0
usemtl red
f 1/1/1 2/2/1 3/3/1
f 1/1/1 3/3/1 4/3/1
g side
usemtl blue
f 1//2 2//2 5//2 4//2
f -1 -2 -3
";

const FUZZ_MTL: &str = "newmtl red
Kd 0.8 0.1 0.1
Ke 0 0 0
map_Kd red.png
newmtl blue
Kd 0.1 0.1 0.8
";

/// Tokens and lines the mutations splice in.
const TOKENS: &[&str] = &[
    "nan",
    "inf",
    "-inf",
    "1e39",
    "1e9",
    "-1e9",
    "0",
    "-0",
    "-1",
    "-99",
    "99",
    "1.5",
    "abc",
    "",
    "/",
    "//",
    "1//",
    "1/1/1/1",
    "-7/-7/-7",
    "1/-9",
    "0/0/0",
    "99999999999999999999",
    "9223372036854775807",
    "-9223372036854775808",
    "4611686018427387904",
    "usemtl",
    "f",
    "v",
    "vt",
    "vn",
    "o",
    "g",
    "mtllib",
    "newmtl",
    "Kd",
    "\t",
    "\u{fffd}",
];

const LINES: &[&str] = &[
    "v nan 0 0",
    "v 1e39 0 0",
    "v 1e9 1 1",
    "v 1 2 3 0",
    "v 1 2 3 1e-30",
    "v 1 2 3 4 5",
    "v 1 2 3 0.5 0.5 0.5",
    "vt 0.5",
    "vn 1e39 0 0",
    "f 1 2 999",
    "f 0 0 0",
    "f -9 -8 -7",
    "f 1/9223372036854775807 2 3",
    "f 1//-5 2 3",
    "f",
    "f 1",
    "f 1 2",
    "f 1 1 1",
    "usemtl",
    "usemtl nope",
    "usemtl  red",
    "mtllib",
    "mtllib missing.mtl",
    "mtllib m.mtl",
    "o",
    "g",
    "s 1",
    "l 1 2",
    "p 1",
    "#",
    "newmtl x",
    "Kd 1",
];

/// One line-level mutation of a text file.
#[derive(Clone, Debug)]
enum Mutation {
    Drop(usize),
    Duplicate(usize),
    ReplaceToken(usize, usize, usize),
    Insert(usize, usize),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        any::<usize>().prop_map(Mutation::Drop),
        any::<usize>().prop_map(Mutation::Duplicate),
        (any::<usize>(), any::<usize>(), 0..TOKENS.len())
            .prop_map(|(l, t, r)| Mutation::ReplaceToken(l, t, r)),
        (any::<usize>(), 0..LINES.len()).prop_map(|(l, r)| Mutation::Insert(l, r)),
    ]
}

fn mutate(text: &str, mutations: &[Mutation]) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    for m in mutations {
        if lines.is_empty() {
            lines.push(String::new());
        }
        let n = lines.len();
        match *m {
            Mutation::Drop(l) => {
                lines.remove(l % n);
            }
            Mutation::Duplicate(l) => {
                let line = lines[l % n].clone();
                lines.insert(l % n, line);
            }
            Mutation::ReplaceToken(l, t, r) => {
                let mut words: Vec<String> =
                    lines[l % n].split_whitespace().map(str::to_owned).collect();
                if words.is_empty() {
                    words.push(String::new());
                }
                let k = t % words.len();
                words[k] = TOKENS[r].to_owned();
                lines[l % n] = words.join(" ");
            }
            Mutation::Insert(l, r) => lines.insert(l % (n + 1), LINES[r].to_owned()),
        }
    }
    lines.join("\n") + "\n"
}

/// Loads the scene and checks the contract: no panic, and an error always
/// explains itself.
fn check_load_contract(path: &Path) -> Result<(), TestCaseError> {
    match scene::load(path) {
        Ok(scene) => {
            prop_assert!(scene.triangle_count() > 0);
            for m in &scene.materials {
                for c in m.albedo {
                    prop_assert!((0.0..=ALBEDO_MAX).contains(&c));
                }
            }
            for p in &scene.positions {
                prop_assert!(p.iter().all(|c| c.is_finite()));
            }
            let _ = scene.summary().to_string();
        }
        Err(e) => prop_assert!(!e.to_string().is_empty()),
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        let dir = temp_dir("fuzz-bytes");
        let path = dir.join("scene.obj");
        std::fs::write(&path, &bytes).unwrap();
        std::fs::write(dir.join("m.mtl"), &bytes).unwrap();
        check_load_contract(&path)?;
        // The same bytes as the material library of a valid OBJ.
        std::fs::write(&path, format!("mtllib m.mtl\nusemtl red\n{QUAD}")).unwrap();
        check_load_contract(&path)?;
    }

    #[test]
    fn mutated_scenes_never_panic(
        obj_mutations in proptest::collection::vec(mutation(), 0..8),
        mtl_mutations in proptest::collection::vec(mutation(), 0..3),
    ) {
        let dir = temp_dir("fuzz-mutations");
        let path = dir.join("scene.obj");
        std::fs::write(&path, mutate(FUZZ_OBJ, &obj_mutations)).unwrap();
        std::fs::write(dir.join("m.mtl"), mutate(FUZZ_MTL, &mtl_mutations)).unwrap();
        check_load_contract(&path)?;
    }
}
