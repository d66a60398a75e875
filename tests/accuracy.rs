//! The bake's accuracy on scenes that are not kind (issue: bake accuracy):
//! thin walls at any position against the grid, closed boxes whose sides
//! divide no voxel size (furnace), surfaces covered by others, and patch
//! irradiance against the independent path tracer (src/reference.rs).

// Index loops over channels and patches read several arrays at once.
#![allow(clippy::needless_range_loop)]

mod common;

use common::{box_inside as room, quad, write_quads, Quad};
use radiosity::bake::voxelize::Resolution;
use radiosity::bake::{self, BakeConfig, CodecChoice, ComputeChoice};
use radiosity::bakefile::codec::CodecKind;
use radiosity::core::scene;
use radiosity::core::scene_config::{self, Light};
use radiosity::generate;
use radiosity::runtime::render::{render, View};
use radiosity::runtime::texture::Albedo;
use radiosity::runtime::{Runtime, RuntimeOptions};
use std::collections::BTreeMap;
use std::path::Path;

fn config(obj: &Path, resolution: Resolution) -> BakeConfig {
    let mut c = BakeConfig::new(obj.to_path_buf(), resolution);
    c.compute = ComputeChoice::OpenCl(Default::default());
    c.codec = CodecChoice::Fixed(CodecKind::default());
    c.error_lights = 0;
    c
}

fn bake_to_runtime(obj: &Path, resolution: Resolution) -> Runtime {
    bake_to_runtime_reporting(obj, resolution).0
}

/// [`bake_to_runtime`], with the bake's report.
fn bake_to_runtime_reporting(obj: &Path, resolution: Resolution) -> (Runtime, bake::BakeReport) {
    let out = obj.with_extension("rad");
    let (baked, output) = common::bake_to(config(obj, resolution), &out);
    let rt = Runtime::new(baked, scene::load(obj).unwrap(), RuntimeOptions::default());
    (rt, output.report)
}

/// Lights `rt` with `light` and checks the dark room (patch centres where
/// `in_dark` holds): every patch there has `H` exactly 0 while the lit
/// room has light, and `camera`'s `Indirect` and `Final` renders are
/// exactly black.
fn assert_dark_room(
    rt: &mut Runtime,
    light: Light,
    camera: scene_config::Camera,
    in_dark: impl Fn([f32; 3]) -> bool,
    what: &str,
) {
    rt.frame(std::slice::from_ref(&light), &BTreeMap::new());
    let (mut lit, mut dark) = (0, 0);
    for (j, p) in rt.baked.patches.iter().enumerate() {
        if in_dark(p.centre) {
            assert!(
                (0..3).all(|c| rt.h()[c][j] == 0.0),
                "{what}: dark-room patch {j} at {:?} gets H",
                p.centre
            );
            dark += 1;
        } else if rt.h()[0][j] > 0.0 {
            lit += 1;
        }
    }
    assert!(
        lit > 0 && dark > 0,
        "{what}: both rooms have patches, the lit one light"
    );
    let config = scene_config::SceneConfig {
        objects: Vec::new(),
        sky: None,
        emission: BTreeMap::new(),
        camera,
        lights: vec![light],
        units: "m".into(),
        description: String::new(),
    };
    let albedo = Albedo::new(&rt.scene);
    for view in [View::Indirect, View::Final] {
        let (img, stats) = render(rt, &config, view, 64, 48, &albedo);
        assert!(stats.hits > 0);
        assert!(
            img.radiance.iter().all(|p| p.iter().all(|&v| v == 0.0)),
            "{what}: the dark room shows light ({view:?})"
        );
    }
}

#[test]
fn thin_walls_at_any_position_let_no_light_into_the_dark_room() {
    let s = 0.25;
    // Wall thickness (voxels) and where it starts within a voxel.
    for &(w, offset) in &[
        (0.5, 0.3),
        (0.1, 0.95),
        (0.04, 0.5),
        (0.01, 0.02),
        (0.01, 0.999),
    ] {
        let x0 = 2.0 + offset * s;
        let x1 = x0 + w * s;
        let mut quads = room([0.0, 0.0, 0.0], [x0, 1.0, 1.0], [0.7; 3]);
        quads.extend(room([x1, 0.0, 0.0], [x1 + 2.0, 1.0, 1.0], [0.6, 0.7, 0.8]));
        let obj = write_quads("acc-walls", &quads);
        let mut rt = bake_to_runtime(&obj, Resolution::VoxelSize(s));
        let light = Light::Point {
            position: [1.0, 0.6, 0.5],
            intensity: [3.0; 3],
        };
        // On pixels: from inside the dark room towards the wall.
        let camera = scene_config::Camera {
            position: [(x1 + 1.9) as f32, 0.5, 0.1],
            target: [x1 as f32, 0.3, 0.6],
            up: [0.0, 1.0, 0.0],
            fov_y_deg: 80.0,
        };
        let what = format!("wall {w} voxels at {offset}");
        assert_dark_room(
            &mut rt,
            light,
            camera,
            |c| c[0] as f64 > 0.5 * (x0 + x1),
            &what,
        );
    }
}

/// A 2.3 × 1 × 1 m room of single quads split by a thin wall from x0 to x1
/// (one quad each side: the face at x0 looks at the lit room, −x, the one
/// at x1 at the dark room, +x), standing on its floor and reaching its
/// ceiling and side walls.
fn room_with_thin_wall(x0: f64, x1: f64) -> Vec<Quad> {
    let mut quads = room([0.0, 0.0, 0.0], [2.3, 1.0, 1.0], [0.7; 3]);
    let h = 0.5;
    quads.push(quad(
        [x0, h, h],
        [0.0, 0.0, 1.0],
        [0.0, 1.0, 0.0],
        h,
        h,
        [0.7; 3],
    ));
    quads.push(quad(
        [x1, h, h],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        h,
        h,
        [0.7; 3],
    ));
    quads
}

/// The light in the lit room of [`room_with_thin_wall`], and a view from
/// inside the dark room towards the wall and the floor along it.
fn thin_wall_light_and_view(x1: f64) -> (Light, scene_config::Camera) {
    let light = Light::Point {
        position: [0.5, 0.6, 0.5],
        intensity: [3.0; 3],
    };
    let camera = scene_config::Camera {
        position: [2.25, 0.9, 0.5],
        target: [x1 as f32, 0.0, 0.5],
        up: [0.0, 1.0, 0.0],
        fov_y_deg: 90.0,
    };
    (light, camera)
}

/// The user's version of the test above: one room whose every face is a
/// single quad, split by a thin wall standing on its floor (and reaching
/// its ceiling and side walls) at any position against the grid. The
/// floor, ceiling and side quads pass under the wall, so their piece in the
/// wall's voxel lies on both sides of it (the voxelizer's "Pieces cut by a
/// wall"); before cuts, the dark room showed up to 30 % of the lit room's
/// peak there.
#[test]
fn a_thin_wall_on_one_big_floor_lets_no_light_into_the_dark_room() {
    let s = 0.25;
    for &(w, offset) in &[
        (0.5, 0.3),
        (0.04, 0.5),
        (0.01, 0.02),
        (0.006, 0.97),
        (0.02, 0.8),
    ] {
        let x0 = 1.0 + offset * s;
        let x1 = x0 + w * s;
        let obj = write_quads("acc-wall-on-floor", &room_with_thin_wall(x0, x1));
        let mut rt = bake_to_runtime(&obj, Resolution::VoxelSize(s));
        let (light, camera) = thin_wall_light_and_view(x1);
        let what = format!("wall {w} voxels at {offset}");
        assert_dark_room(&mut rt, light, camera, |c| c[0] as f64 > x1, &what);
        // The case under test arose: some piece was cut by the wall.
        let cut = rt.baked.surface_map.cuts.len();
        assert!(cut > 0, "wall {w} voxels at {offset}: no piece was cut");
    }
}

/// Fragments (patches far smaller than a voxel face, module
/// `voxelize::fragments`) join a neighbour facing the same way, but never
/// across a wall: blocks of a fifth of a voxel hang in the air on both
/// sides of a thin wall, 2 cm from it, and stand on the floor a voxel
/// away, and the dark room stays exactly dark while fragments were
/// joined. (Blocks standing on the floor 2 cm from the wall let light
/// through with or without fragments: the floor piece under the wall is
/// then cut along a block's side, not the wall's; see the closing note of
/// issue 42.)
#[test]
fn clutter_by_a_thin_wall_joins_no_fragment_across_it() {
    let s = 0.25;
    let (x0, x1) = (1.0 + 0.6 * s, 1.0 + 0.64 * s);
    let mut quads = room_with_thin_wall(x0, x1);
    // Blocks hanging 2 cm from the wall (fragments in the wall's voxel,
    // facing the same ways on both sides), and standing on the floor a
    // voxel away from it.
    let b = 0.05;
    for z in [0.15, 0.45, 0.75] {
        for (y, gap) in [(0.5, 0.02), (0.7, 0.02), (0.0, 0.3)] {
            quads.extend(common::block(
                [x0 - gap - b, y, z],
                [x0 - gap, y + b, z + b],
                [0.6; 3],
            ));
            quads.extend(common::block(
                [x1 + gap, y, z],
                [x1 + gap + b, y + b, z + b],
                [0.6; 3],
            ));
        }
    }
    let obj = write_quads("acc-clutter-wall", &quads);
    let (mut rt, report) = bake_to_runtime_reporting(&obj, Resolution::VoxelSize(s));
    assert!(
        report.voxels.fragments_joined > 0,
        "the case under test arose: fragments were joined ({:?})",
        report.voxels
    );
    let (light, camera) = thin_wall_light_and_view(x1);
    assert_dark_room(
        &mut rt,
        light,
        camera,
        |c| c[0] as f64 > x1,
        "clutter by the wall",
    );
}

/// Writes `quads` with emission 1 on every material (Ke appended to the
/// MTL) and bakes them at `voxel`.
fn bake_emitting(tag: &str, quads: &[Quad], voxel: f64) -> bake::BakeOutput {
    let obj = write_quads(tag, quads);
    let mtl = obj.with_file_name("scene.mtl");
    let text = std::fs::read_to_string(&mtl)
        .unwrap()
        .replace("Kd", "Ke 1 1 1\nKd");
    std::fs::write(&mtl, text).unwrap();
    let c = config(&obj, Resolution::VoxelSize(voxel));
    common::gpu();
    bake::run(&c, &mut |_| {}).expect("bake")
}

/// The furnace measures of a bake with uniform albedo `rho` and emission 1
/// everywhere: the largest `|row sum − 1|` of `F` and the largest relative
/// error of `H = T_∞ E` (uncompressed, f32) against the exact `1 / (1 − ρ)`,
/// with the patches whose rows are off by more than `row_tol`, for the
/// failure message.
fn furnace_errors(out: &bake::BakeOutput, rho: f64, row_tol: f64) -> (f64, f64, String) {
    let ff = &out.form_factors;
    let rows = ff.row_sums();
    let worst_row = rows.iter().map(|s| (s - 1.0).abs()).fold(0.0, f64::max);
    let mut off = String::new();
    for (k, r) in rows.iter().enumerate() {
        if (r - 1.0).abs() > row_tol {
            let p = &out.patches[k];
            off += &format!(
                "\n  row {k}: {r} centre {:?} normal {:?} area {}",
                p.centre, p.normal, p.area
            );
        }
    }
    let n = ff.n;
    let t = out.transfer.channel(0);
    let exact = 1.0 / (1.0 - rho);
    let worst_h = (0..n)
        .map(|i| {
            let h: f64 = t[i * n..(i + 1) * n].iter().map(|&v| v as f64).sum();
            (h / exact - 1.0).abs()
        })
        .fold(0.0, f64::max);
    (worst_row, worst_h, off)
}

#[test]
fn furnace_in_boxes_whose_sides_divide_no_voxel_size() {
    // Closed boxes, every face one quad (two triangles), uniform albedo ρ
    // and emission 1: the exact irradiance from emission is 1 / (1 − ρ) on
    // every patch, whatever the patching, if every row of F sums to 1.
    for &(size, voxel) in &[
        ([1.37, 0.83, 2.11], 0.2),
        ([2.0, 1.0, 3.0], 0.23),
        ([1.004, 1.0, 0.5], 0.25), // a 0.004 sliver column along one side
    ] {
        for &rho in &[0.9, 0.99] {
            let mut quads = room([0.0; 3], size, [rho; 3]);
            for q in &mut quads {
                q.albedo = [rho; 3];
            }
            let out = bake_emitting("acc-furnace", &quads, voxel);
            let (worst_row, worst, off) = furnace_errors(&out, rho, 0.005);
            assert!(
                worst_row < 0.005,
                "box {size:?} at voxel {voxel}: a row sums {worst_row} away from 1{off}"
            );
            let tol = if rho < 0.95 { 0.01 } else { 0.05 };
            assert!(
                worst < tol,
                "box {size:?} at voxel {voxel}, ρ {rho}: furnace H off by {worst:.4} (> {tol})"
            );
        }
    }
}

#[test]
fn an_outward_wound_box_is_refused_and_bakes_two_sided() {
    // A closed box whose faces point out (a common export): from their
    // fronts the walls see nothing, from their backs only the backs of the
    // other walls. The bake stops naming the cause; two-sided, the inner
    // sides form a closed box that passes the furnace test, and the outer
    // sides (half the area) are the patches that see nothing.
    let rho = 0.9;
    let mut quads = room([0.0; 3], [1.3, 0.9, 1.7], [rho; 3]);
    for q in &mut quads {
        q.corners.reverse();
    }
    let obj = write_quads("acc-outward", &quads);
    let mtl = obj.with_file_name("scene.mtl");
    let text = std::fs::read_to_string(&mtl)
        .unwrap()
        .replace("Kd", "Ke 1 1 1\nKd");
    std::fs::write(&mtl, text).unwrap();
    common::gpu();
    let mut c = config(&obj, Resolution::VoxelSize(0.21));
    let err = bake::run(&c, &mut |_| {})
        .err()
        .expect("an outward-wound box must not bake");
    // A typed error: the facing stage's, whose message names the cause.
    assert!(
        matches!(err, bake::error::BakeError::Facing { .. }),
        "{err}"
    );
    let root = err.to_string();
    assert!(
        root.contains("wound away from each other") && root.contains("two-sided"),
        "{root}"
    );
    c.two_sided = true;
    let out = bake::run(&c, &mut |_| {}).expect("two-sided bake");
    let blind = out.report.facing.blind_area_share;
    // Patch areas are sums of f32 piece areas: 1e-6 relative.
    assert!((blind - 0.5).abs() < 1e-6, "blind share {blind}");
    // As the furnace in one-sided boxes (above): rows within 0.5 %, H
    // within 1 %.
    let (worst_row, worst, off) = furnace_errors(&out, rho, 0.005);
    assert!(worst_row < 0.005, "a row sums {worst_row} away from 1{off}");
    assert!(worst < 0.01, "furnace H off by {worst:.4}");
    assert!(out.file.options_json.contains("\"two_sided\":true"));
}

/// A 10 m room on a 10 km ground plane (a building on its site, as
/// architectural scenes come): at a few hundred patches a voxel is some
/// hundreds of metres wide, the room falls inside one voxel and the flat
/// ground sees nothing. The bake is refused with the voxel size and the
/// cause, not a bare "nothing to bake".
#[test]
fn a_room_on_a_huge_ground_is_refused_naming_the_voxel() {
    let mut quads = room([-5.0, 0.0, -5.0], [5.0, 4.0, 5.0], [0.7; 3]);
    quads.push(quad(
        [0.0, -0.01, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 0.0],
        5000.0,
        5000.0,
        [0.3; 3],
    ));
    let obj = write_quads("acc-site", &quads);
    common::gpu();
    let err = bake::run(&config(&obj, Resolution::Patches(400)), &mut |_| {})
        .err()
        .expect("a room inside one voxel must not bake");
    // A typed error: the facing stage's, whose message names the cause.
    assert!(
        matches!(err, bake::error::BakeError::Facing { .. }),
        "{err}"
    );
    let root = err.to_string();
    assert!(
        root.contains("no patch sees another surface")
            && root.contains("voxels")
            && root.contains("ground"),
        "{root}"
    );
}

/// Some faces wound the wrong way: a room with two of its six walls
/// flipped gets back sides on those walls (crates/bake/src/winding.rs), named in
/// the bake's summary, and bakes without a warning. Emitting faces get no
/// back side (a panel emits from its front only), so with the two walls
/// emitting they lose their patches and the bake warns and names their
/// materials (crates/bake/src/facing.rs, "Some faces reversed"); the same room
/// wound right, and an open scene whose box top faces the sky (blind, with
/// only backs behind it), bake without the warning.
#[test]
fn a_room_with_some_walls_wound_the_wrong_way_gets_back_sides_or_a_warning_naming_them() {
    let mut quads = room([0.0, 0.0, 0.0], [1.3, 1.0, 1.1], [0.6; 3]);
    // room() pushes −x, +x, −y, +y, −z, +z: flip +x (m1) and +z (m5).
    for k in [1, 5] {
        quads[k].corners.reverse();
    }
    let obj = write_quads("acc-some-flipped", &quads);
    common::gpu();
    let out = bake::run(&config(&obj, Resolution::VoxelSize(0.2)), &mut |_| {}).expect("bake");
    let w = &out.report.winding;
    assert_eq!(w.twinned.len(), 4, "{w}");
    let named: Vec<&str> = w.materials.iter().map(|(m, _)| m.as_str()).collect();
    assert_eq!(named.len(), 2, "{w}");
    assert!(named.contains(&"m1") && named.contains(&"m5"), "{w}");
    let f = &out.report.facing;
    assert!(f.warnings.is_empty(), "{:?}", f.warnings);
    assert_eq!(f.reversed_patches, 0);

    // The flipped walls emitting: no back sides, a warning.
    let mtl = obj.with_file_name("scene.mtl");
    let text = std::fs::read_to_string(&mtl).unwrap();
    let text = text
        .replace("newmtl m1\n", "newmtl m1\nKe 1 1 1\n")
        .replace("newmtl m5\n", "newmtl m5\nKe 1 1 1\n");
    std::fs::write(&mtl, text).unwrap();
    let out = bake::run(&config(&obj, Resolution::VoxelSize(0.2)), &mut |_| {}).expect("bake");
    assert!(out.report.winding.is_empty(), "{}", out.report.winding);
    let f = &out.report.facing;
    assert_eq!(f.warnings.len(), 1, "{:?}", f.warnings);
    let w = &f.warnings[0];
    assert!(
        w.contains("wound the wrong way") && w.contains("`m1`") && w.contains("`m5`"),
        "{w}"
    );
    assert!(w.contains("two-sided"), "{w}");
    // The two walls are 1.0 × 1.1 and 1.3 × 1.0 of the 7.66 m² room.
    let share = (1.1 + 1.3) / (2.0 * (1.3 + 1.43 + 1.1));
    assert!(
        (f.reversed_area_share - share).abs() < 0.02,
        "reversed share {} against {share}",
        f.reversed_area_share
    );

    let right = write_quads(
        "acc-none-flipped",
        &room([0.0; 3], [1.3, 1.0, 1.1], [0.6; 3]),
    );
    let out = bake::run(&config(&right, Resolution::VoxelSize(0.2)), &mut |_| {}).expect("bake");
    assert!(out.report.facing.warnings.is_empty());
    assert_eq!(out.report.facing.reversed_patches, 0);

    // A floor with a bottomless box on it, under the sky. (Its sides lie in
    // voxel faces, x = 0.3 at voxel 0.1: before FACE_SLACK in
    // crates/core/src/patch.rs, the OpenCL voxelizer put them in the voxels where
    // the host's clip found no polygon, and this bake saw nothing.)
    let mut open = vec![quad(
        [0.5, 0.0, 0.5],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 0.0],
        0.5,
        0.5,
        [0.6; 3],
    )];
    open.extend(bottomless_box([0.3, 0.0, 0.3], [0.7, 0.4, 0.7], [0.6; 3]));
    let open = write_quads("acc-open-box", &open);
    let out = bake::run(&config(&open, Resolution::VoxelSize(0.1)), &mut |_| {}).expect("bake");
    let f = &out.report.facing;
    // The box top (0.16 of 1.8 m²) faces the sky.
    assert!(
        f.blind_area_share > 0.05,
        "blind share {}",
        f.blind_area_share
    );
    assert!(f.warnings.is_empty(), "{:?}", f.warnings);
}

/// The outward faces of the box `[lo, hi]` without its bottom (a box
/// standing on a floor, as the Cornell box's blocks are modelled).
fn bottomless_box(lo: [f64; 3], hi: [f64; 3], a: [f64; 3]) -> Vec<Quad> {
    room(lo, hi, a)
        .into_iter()
        .enumerate()
        // room() pushes the faces axis by axis, −side first: index 2 is
        // the face at y = lo.
        .filter(|&(k, _)| k != 2)
        .map(|(_, mut q)| {
            q.corners.reverse();
            q
        })
        .collect()
}

#[test]
fn furnace_with_a_bottomless_box_on_the_floor() {
    // The floor under the box is enclosed (every ray from it meets the
    // box's inside, a back face): covered, in no patch. The floor pieces
    // the box's walls cut are partly covered; their patches stand for the
    // visible part only, whose rays all meet front faces, so every row
    // sums to 1 and the furnace holds beside the box as everywhere
    // (before: rows down to ~0.5 there, and the visible floor beside the
    // box dark).
    let rho = 0.9;
    let mut quads = room([0.0; 3], [1.37, 0.83, 2.11], [rho; 3]);
    quads.extend(bottomless_box(
        [0.41, 0.0, 0.53],
        [0.87, 0.37, 1.09],
        [rho; 3],
    ));
    let out = bake_emitting("acc-furnace-box", &quads, 0.2);
    let v = &out.report.voxels;
    let footprint = 0.46 * 0.56;
    let up = v.covered_area_per_direction[2];
    assert!(
        (up / footprint - 1.0).abs() < 0.05,
        "covered floor {up}, the box stands on {footprint}"
    );
    let (worst_row, worst, off) = furnace_errors(&out, rho, 0.005);
    assert!(worst_row < 0.005, "a row sums {worst_row} away from 1{off}");
    assert!(worst < 0.01, "furnace H off by {worst:.4}");
}

#[test]
fn covered_surfaces_are_dropped_and_the_panel_keeps_its_power() {
    let dir = common::temp_dir("acc-panel");
    generate::write_bundled("cornell_panel", &dir).unwrap();
    let obj = dir.join("cornell_panel.obj");
    let mut c = config(&obj, Resolution::Patches(600));
    c.output = Some(dir.join("cornell_panel.rad"));
    common::gpu();
    let out = bake::run(&c, &mut |_| {}).expect("bake");
    let v = &out.report.voxels;
    // The ceiling above the panel (1 cm behind it) is covered: its area
    // (0.09 m², facing −y) is reported and not part of any patch.
    let down = v.covered_area_per_direction[3];
    assert!(
        (down - 0.09).abs() < 0.09 * 0.25,
        "covered area facing down {down}, the hidden ceiling is 0.09 m²"
    );
    assert!(v.covered_pieces > 0);
    // The panel's power: Σ A_j E_j over the patches equals 0.09 m² × Ke.
    let power: [f64; 3] = std::array::from_fn(|ch| {
        out.patches
            .iter()
            .map(|p| p.area * p.emission[ch])
            .sum::<f64>()
    });
    for (ch, ke) in [17.0, 12.0, 4.0].iter().enumerate() {
        let want = 0.09 * ke;
        assert!(
            (power[ch] / want - 1.0).abs() < 1e-3,
            "channel {ch}: emitted power {} against {want}",
            power[ch]
        );
    }
}

#[test]
fn patch_irradiance_matches_the_path_tracer_on_a_cornell_box_with_a_panel() {
    let dir = common::temp_dir("acc-pt");
    generate::write_bundled("cornell_panel", &dir).unwrap();
    let obj = dir.join("cornell_panel.obj");
    let mut c = config(&obj, Resolution::Patches(500));
    c.output = Some(dir.join("cornell_panel.rad"));
    common::gpu();
    bake::run(&c, &mut |_| {}).expect("bake");
    let lights = scene_config::load(&dir.join("cornell_panel.json")).unwrap();
    let (report, text) = radiosity::bench::accuracy::run(
        &dir.join("cornell_panel.rad"),
        &lights,
        4096,
        4,
        None,
        None,
        true,
    )
    .unwrap();
    println!("{text}");
    // Targets: 5 % bias, 10 % relative RMS (area-weighted, three channels
    // pooled), against a reference whose own noise is reported, small, and
    // taken out of the RMS in quadrature (independent errors add so).
    let t = &report.total;
    assert!(t.noise < 0.05, "{text}");
    assert!(t.bias.abs() < 0.05, "{text}");
    let rms = (t.rel_rms * t.rel_rms - t.noise * t.noise).max(0.0).sqrt();
    assert!(
        rms < 0.10,
        "RMS without the reference's noise {rms:.4}: {text}"
    );
}

#[test]
fn the_default_codec_stays_within_two_percent_on_every_scene() {
    // The default bake chooses the cheapest codec setting within 2 % of H
    // (relative RMS over 64 seeded lights) instead of a fixed one, which
    // misses 2 % on some scenes.
    let dir = common::temp_dir("acc-codec");
    generate::write_bundled("cornell_published", &dir).unwrap();
    for obj in [
        common::bundled("cornell_box"),
        common::bundled("interior"),
        dir.join("cornell_published.obj"),
    ] {
        let mut c = BakeConfig::new(obj.clone(), Resolution::Patches(800));
        c.compute = ComputeChoice::OpenCl(Default::default());
        assert_eq!(c.codec, CodecChoice::MaxError(0.02), "the default");
        common::gpu();
        let out = bake::run(&c, &mut |_| {}).expect("bake");
        let e = out.report.codec.h_error.expect("measured");
        assert!(
            e <= 0.02,
            "{}: H error {e} with {}",
            obj.display(),
            out.report.codec.codec
        );
        // The setting must still compress: F16 (6 bytes per entry) passes
        // any bound, BC1 with up to a quarter of the entries sparse stays
        // under 2 bytes (0.5 dense + 6 per sparse position × 0.24).
        let bytes = out.report.codec.bytes_per_entry;
        assert!(
            bytes < 2.0,
            "{}: {bytes} bytes per entry",
            out.report.codec.codec
        );
    }
}

/// A gallery under a sun: a floor, a back wall and a roof slab over the
/// floor along the wall, open elsewhere. The sun slants under the roof's
/// edge, so a strip of floor under the roof is sunlit while the wall
/// beneath the roof is in shadow and sees that strip up close — the case
/// where one exitance per floor patch is wrong for its nearest neighbours
/// (Sponza's colonnades, docs/accuracy.md).
fn gallery() -> Vec<Quad> {
    let grey = [0.6, 0.6, 0.6];
    vec![
        // Floor, facing +y.
        quad(
            [3.0, 0.0, 2.0],
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 0.0],
            2.0,
            3.0,
            grey,
        ),
        // Back wall at x = 0, facing +x.
        quad(
            [0.0, 1.5, 2.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            1.5,
            2.0,
            grey,
        ),
        // Roof slab at y = 2 over x in [0, 1.6], facing down.
        quad(
            [0.8, 2.0, 2.0],
            [1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0],
            0.8,
            2.0,
            grey,
        ),
    ]
}

#[test]
fn the_near_field_correction_brings_a_sunlit_gallery_closer_to_the_path_tracer() {
    let obj = write_quads("acc-gallery", &gallery());
    let out = obj.with_extension("rad");
    let mut c = config(&obj, Resolution::VoxelSize(0.9));
    c.output = Some(out.clone());
    common::gpu();
    let bake = bake::run(&c, &mut |_| {}).expect("bake");
    assert!(
        bake.report.near_field.links > 0,
        "near-field links were found"
    );
    let mut lights =
        scene_config::load(&common::bundled("cornell_box").with_extension("json")).unwrap();
    lights.lights = vec![Light::Directional {
        direction: [-0.5, -1.0, 0.0],
        irradiance: [10.0, 10.0, 10.0],
    }];
    let run = |near: bool| {
        radiosity::bench::accuracy::run(&out, &lights, 1024, 16, None, None, near).unwrap()
    };
    let (with, text_with) = run(true);
    let (without, text_without) = run(false);
    println!("with the correction:\n{text_with}without:\n{text_without}");
    let clean = |c: &radiosity::bench::accuracy::Comparison| {
        (c.rel_rms * c.rel_rms - c.noise * c.noise).max(0.0).sqrt()
    };
    let (a, b) = (clean(&with.total), clean(&without.total));
    // Measured 5.3 % against 7.5 % (1,024 paths per point, 65 patches;
    // 4.9 % against 7.0 % before cuts).
    assert!(
        a < 0.75 * b,
        "RMS without the reference's noise: {a:.4} with the correction, {b:.4} without"
    );
    // Measured −5.0 % with, −2.3 % without. The correction moves light
    // between neighbours (its weights sum to zero per link) but not evenly
    // over receivers' areas: here the shadowed wall under the roof sees the
    // floor's dark strip by the wall more than the patch mean says. Before
    // the back wall's piece at the roof was cut (crates/bake/src/cut.rs) it was
    // −3.9 % / +0.8 %: that piece reached 0.7 m above the roof and its
    // patch, 3/4 sunlit, sent sunlight under the roof; cut, the part under
    // the roof matches the path tracer to 0.1 % and the part above sees
    // nothing. What is left low is mostly the floor patch under the roof's
    // shadow edge, 1/3 sunlit, whose 16 sample points find 1/4 lit. The
    // bound: the panel test's 5 % plus the 1 % that leak had been hiding.
    assert!(
        with.total.bias.abs() < 0.06,
        "bias {:.4} with the correction ({:.4} without)",
        with.total.bias,
        without.total.bias
    );
}

/// A floor under a roof with slots 0.04 wide (16 % of the 0.25 voxel)
/// against a sides of voxels, and a vertical sun: the sunlit floor is the
/// slots exactly. Slots run along x over one half of the floor (at the low
/// and the high end of alternate voxel rows in z) and along z over the
/// other half (the same in x), so that both in-plane axes of the floor
/// patches and both ends of each are tried.
fn slotted_roof() -> (Vec<Quad>, Vec<[f64; 4]>) {
    let grey = [0.5, 0.5, 0.5];
    let (voxel, w, y_floor, y_roof) = (0.25, 0.04, 0.1, 0.6);
    // Floor [0, 2] × [0, 2] at y = 0.1, facing +y.
    let mut quads = vec![quad(
        [1.0, y_floor, 1.0],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 0.0],
        1.0,
        1.0,
        grey,
    )];
    // Slots as (x0, x1, z0, z1), and the roof's gaps between them per half.
    let mut slots = Vec::new();
    let end = |k: usize| {
        let lo = voxel * k as f64;
        if k.is_multiple_of(2) {
            (lo, lo + w)
        } else {
            (lo + voxel - w, lo + voxel)
        }
    };
    // Half x in [1, 2]: slots along x, by z.
    let mut z = 0.0;
    for k in 0..8 {
        let (a, b) = end(k);
        slots.push([1.0, 2.0, a, b]);
        if a > z {
            quads.push(roof([1.0, 2.0], [z, a], y_roof, grey));
        }
        z = b;
    }
    if z < 2.0 {
        quads.push(roof([1.0, 2.0], [z, 2.0], y_roof, grey));
    }
    // Half x in [0, 1]: slots along z, by x.
    let mut x = 0.0;
    for k in 0..4 {
        let (a, b) = end(k);
        slots.push([a, b, 0.0, 2.0]);
        if a > x {
            quads.push(roof([x, a], [0.0, 2.0], y_roof, grey));
        }
        x = b;
    }
    if x < 1.0 {
        quads.push(roof([x, 1.0], [0.0, 2.0], y_roof, grey));
    }
    (quads, slots)
}

/// A roof rectangle `x × z` at height `y`, facing down.
fn roof(x: [f64; 2], z: [f64; 2], y: f64, albedo: [f64; 3]) -> Quad {
    quad(
        [0.5 * (x[0] + x[1]), y, 0.5 * (z[0] + z[1])],
        [1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
        0.5 * (x[1] - x[0]),
        0.5 * (z[1] - z[0]),
        albedo,
    )
}

/// The patches' direct light must see a strip of sun along any side of a
/// patch: their sample points are a (0, 2)-sequence whose first 16 points
/// have one point in each sixteenth of a patch along either axis, so a
/// slot 16 % wide holds at least one. (The R2 points used before left the
/// last 17.7 % of one axis empty on every patch, and Sponza's floor next to
/// its courtyard lost its sun that way.) Every floor patch under a slot
/// gets light, and the floor's sunlit power `Σ A_j D_j` is within 6 % of
/// the exact `E · (slot area)`: each patch's estimate is unbiased (its
/// sequence is shifted by a seed of its own) with a standard deviation of
/// about 1/16 of the patch for a slot's edge, so over the 64 slot crossings
/// the sum's is about 2 %; 6 % is three of those.
#[test]
fn a_strip_of_sun_along_any_side_of_a_patch_reaches_its_direct_light() {
    let (quads, slots) = slotted_roof();
    let obj = write_quads("acc-slots", &quads);
    let rt = bake_to_runtime(&obj, Resolution::VoxelSize(0.25));
    let e = 10.0;
    let sun = [Light::Directional {
        direction: [0.0, -1.0, 0.0],
        irradiance: [e as f32; 3],
    }];
    let d = radiosity::runtime::direct::patch_irradiance(
        &rt.baked,
        &rt.direct,
        &sun,
        radiosity::bakefile::surface::SAMPLES_PER_PATCH,
    );
    let (mut power, mut floor_patches) = (0.0f64, 0);
    for (j, p) in rt.baked.patches.iter().enumerate() {
        if !(p.normal[1] > 0.99 && p.centre[1] < 0.3) {
            continue;
        }
        floor_patches += 1;
        power += p.area as f64 * d[1][j] as f64;
        // Slots inside this patch's voxel square (the floor is aligned
        // with the grid, so each floor patch is one voxel square).
        let (cx, cz) = (p.centre[0] as f64, p.centre[2] as f64);
        let inside = |s: &[f64; 4]| {
            let (x0, x1) = (s[0].max(cx - 0.125), s[1].min(cx + 0.125));
            let (z0, z1) = (s[2].max(cz - 0.125), s[3].min(cz + 0.125));
            x1 - x0 > 1e-9 && z1 - z0 > 1e-9
        };
        if slots.iter().any(inside) {
            assert!(
                d[1][j] > 0.0,
                "the floor patch at ({cx:.3}, {cz:.3}) has a slot of sun and got no direct light"
            );
        }
    }
    assert_eq!(floor_patches, 64, "the floor is 8 × 8 patches");
    let exact: f64 = slots
        .iter()
        .map(|s| e * (s[1] - s[0]) * (s[3] - s[2]))
        .sum();
    let rel = power / exact - 1.0;
    assert!(
        rel.abs() < 0.06,
        "the floor's sunlit power {power:.4} against exactly {exact:.4} ({:+.1} %)",
        100.0 * rel
    );
}
