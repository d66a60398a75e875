//! The mesh-to-patch map: no light through thin walls, floors take light
//! from floors, weights are a partition of unity, linear fields are
//! reproduced with an error confined to surface edges and falling with the
//! voxel size, every vertex of the Cornell box and Sponza is mapped, and
//! the result is deterministic.

mod common;

use radiosity::bake::form_factor::shift_of;
use radiosity::bake::mesh_map::{self, MeshMap, MeshMapOptions, Outcome};
use radiosity::bake::voxelize::Cover;
use radiosity::bake::voxelize::{voxelize_at, Voxelization};
use radiosity::core::bvh::Bvh;
use radiosity::core::compute::Backend;
use radiosity::core::scene::{self, Scene};
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

/// A triangle mesh under construction.
#[derive(Default)]
struct Mesh {
    v: Vec<[f64; 3]>,
    f: Vec<[usize; 3]>,
}

impl Mesh {
    /// A rectangle from `corner` spanned by `eu`, `ev`, cut into `nu × nv`
    /// cells, facing `eu × ev` (counter-clockwise seen from its front), with
    /// its own vertices.
    fn rect(&mut self, corner: [f64; 3], eu: [f64; 3], ev: [f64; 3], nu: usize, nv: usize) {
        let base = self.v.len();
        for j in 0..=nv {
            for i in 0..=nu {
                let (a, b) = (i as f64 / nu as f64, j as f64 / nv as f64);
                self.v
                    .push(std::array::from_fn(|k| corner[k] + a * eu[k] + b * ev[k]));
            }
        }
        let at = |i: usize, j: usize| base + j * (nu + 1) + i;
        for j in 0..nv {
            for i in 0..nu {
                self.f.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                self.f.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
    }

    /// Writes the mesh as an OBJ with one grey material (and, if given, one
    /// normal per vertex) and returns its path.
    fn write(&self, tag: &str, normals: Option<&[[f64; 3]]>) -> PathBuf {
        let dir = common::temp_dir(tag);
        let mut obj = String::from("mtllib scene.mtl\nusemtl grey\n");
        for p in &self.v {
            writeln!(
                obj,
                "v {:?} {:?} {:?}",
                p[0] as f32, p[1] as f32, p[2] as f32
            )
            .unwrap();
        }
        if let Some(ns) = normals {
            for n in ns {
                writeln!(
                    obj,
                    "vn {:?} {:?} {:?}",
                    n[0] as f32, n[1] as f32, n[2] as f32
                )
                .unwrap();
            }
        }
        for t in &self.f {
            let [a, b, c] = t.map(|i| i + 1);
            if normals.is_some() {
                writeln!(obj, "f {a}//{a} {b}//{b} {c}//{c}").unwrap();
            } else {
                writeln!(obj, "f {a} {b} {c}").unwrap();
            }
        }
        std::fs::write(dir.join("scene.mtl"), "newmtl grey\nKd 0.5 0.5 0.5\n").unwrap();
        let path = dir.join("scene.obj");
        std::fs::write(&path, obj).unwrap();
        path
    }
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Area-weighted vertex normals of a loaded scene (by vertex index); zero
/// where the faces' normals cancel (|Σ A n| ≤ 1e-3 Σ A), as the module
/// treats them.
fn face_normals(scene: &Scene) -> Vec<[f64; 3]> {
    let mut n = vec![[0.0; 3]; scene.positions.len()];
    let mut total = vec![0.0; scene.positions.len()];
    for (t, tri) in scene.triangles.iter().enumerate() {
        let g = scene.triangle_normal(t);
        let a = scene.triangle_area(t);
        for &v in tri {
            total[v as usize] += a;
            for k in 0..3 {
                n[v as usize][k] += a * g[k];
            }
        }
    }
    n.iter()
        .zip(&total)
        .map(|(v, t)| {
            let l = dot(*v, *v).sqrt();
            if l > 1e-3 * t {
                v.map(|x| x / l)
            } else {
                [0.0; 3]
            }
        })
        .collect()
}

fn identity(vox: &Voxelization) -> Vec<Option<u32>> {
    (0..vox.patches.len() as u32).map(Some).collect()
}

/// Every row: weights finite, ≥ 0, summing to 1 (within the bake file's
/// tolerance) or all zero, unused slots `(0, 0.0)`, indices valid; and every
/// used patch faces the vertex's side (`n · N > 0`). Returns the number of
/// rows with no patch.
fn check_rows(scene: &Scene, vox: &Voxelization, map: &MeshMap, of_matrix: &[usize]) -> usize {
    let normals = face_normals(scene);
    let mut empty = 0;
    assert_eq!(map.entries.len(), scene.positions.len());
    for (v, row) in map.entries.iter().enumerate() {
        let mut sum = 0.0f64;
        for &(p, w) in row {
            assert!(w.is_finite() && w >= 0.0, "vertex {v}: weight {w}");
            if w == 0.0 {
                assert_eq!(p, 0, "vertex {v}: unused slot");
                continue;
            }
            let patch = &vox.patches[of_matrix[p as usize]];
            assert!(
                normals[v] == [0.0; 3] || dot(patch.normal, normals[v]) > 0.0,
                "vertex {v} at {:?} (normal {:?}) uses patch {p} facing {:?}",
                scene.positions[v],
                normals[v],
                patch.normal
            );
            sum += w as f64;
        }
        if sum == 0.0 {
            empty += 1;
        } else {
            assert!(
                (sum - 1.0).abs() <= 1e-6,
                "vertex {v}: weights sum to {sum}"
            );
        }
        // Weights in decreasing order.
        assert!(
            row.windows(2).all(|p| p[0].1 >= p[1].1),
            "vertex {v}: {row:?}"
        );
    }
    empty
}

/// A 4 × 4 floor with a two-sided wall 0.05 thick standing on it inside one
/// layer of 0.25 voxels (x in [0.19, 0.24]), 1 high, with its top face.
fn thin_wall_scene() -> Scene {
    let mut m = Mesh::default();
    let (x0, x1) = (0.19, 0.24);
    // Floor on each side, facing +y (z × x = y).
    m.rect(
        [-2.0, 0.0, -2.0],
        [0.0, 0.0, 4.0],
        [x0 + 2.0, 0.0, 0.0],
        40,
        22,
    );
    m.rect(
        [x1, 0.0, -2.0],
        [0.0, 0.0, 4.0],
        [2.0 - x1, 0.0, 0.0],
        40,
        18,
    );
    // Wall faces: −x at x0 (y × z = x, so z × y), +x at x1.
    m.rect([x0, 0.0, -2.0], [0.0, 0.0, 4.0], [0.0, 1.0, 0.0], 40, 10);
    m.rect([x1, 0.0, -2.0], [0.0, 1.0, 0.0], [0.0, 0.0, 4.0], 10, 40);
    // Top, facing +y.
    m.rect([x0, 1.0, -2.0], [0.0, 0.0, 4.0], [x1 - x0, 0.0, 0.0], 40, 1);
    scene::load(&m.write("meshmap-thinwall", None)).unwrap()
}

#[test]
fn thin_wall_vertices_take_light_only_from_their_own_side() {
    let scene = thin_wall_scene();
    let vox = voxelize_at(&scene, 0.25, &Backend::Cpu).unwrap();
    let ids = identity(&vox);
    let of_matrix: Vec<usize> = (0..vox.patches.len()).collect();
    let map = mesh_map::build(&scene, &vox, &ids).unwrap();
    assert_eq!(
        check_rows(&scene, &vox, &map, &of_matrix),
        0,
        "every vertex mapped"
    );
    let normals = face_normals(&scene);
    let (x0, x1) = (0.19f32, 0.24f32);
    let mut counts = [0usize; 4];
    let mut leaks_without_visibility = 0;
    let blind = mesh_map::build_with(
        &scene,
        &vox,
        &ids,
        &MeshMapOptions {
            visibility: false,
            ..Default::default()
        },
    )
    .unwrap();
    for (v, row) in map.entries.iter().enumerate() {
        let p = scene.positions[v];
        let n = normals[v];
        let used: Vec<&radiosity::core::patch::Patch> = row
            .iter()
            .filter(|s| s.1 > 0.0)
            .map(|s| &vox.patches[s.0 as usize])
            .collect();
        // Every patch used agrees with the vertex normal within 60°.
        for q in &used {
            assert!(
                dot(q.normal, n) >= 0.5,
                "vertex {v} at {p:?}, normal {n:?}: patch facing {:?}",
                q.normal
            );
        }
        if n[0] < -0.9 {
            // The wall's −x side: only patches facing −x.
            counts[0] += 1;
            assert!(
                used.iter().all(|q| q.normal[0] < -0.9),
                "vertex {v} at {p:?}"
            );
        } else if n[0] > 0.9 {
            counts[1] += 1;
            assert!(
                used.iter().all(|q| q.normal[0] > 0.9),
                "vertex {v} at {p:?}"
            );
        } else if n[1] > 0.9 && p[1] == 0.0 {
            // Floor: floor patches only (never the wall's), and never from
            // across the wall.
            assert!(used
                .iter()
                .all(|q| q.normal[1] > 0.9 && q.centre[1].abs() < 1e-6));
            let blind_used = blind.entries[v].iter().filter(|s| s.1 > 0.0);
            if p[0] <= x0 {
                counts[2] += 1;
                assert!(
                    used.iter().all(|q| q.centre[0] < x1 as f64),
                    "side A vertex {v} at {p:?} takes light from side B: {used:?}"
                );
            } else {
                assert!(p[0] >= x1);
                counts[3] += 1;
                assert!(
                    used.iter().all(|q| q.centre[0] > x0 as f64),
                    "side B vertex {v} at {p:?} takes light from side A: {used:?}"
                );
                leaks_without_visibility += blind_used
                    .filter(|s| vox.patches[s.0 as usize].centre[0] < x0 as f64)
                    .count();
            }
        }
    }
    println!(
        "thin wall: {} patches; vertices −x {}, +x {}, floor A {}, floor B {}; {:?}; \
         without the visibility test {} (vertex, patch) pairs would cross the wall",
        vox.patches.len(),
        counts[0],
        counts[1],
        counts[2],
        counts[3],
        map.stats,
        leaks_without_visibility
    );
    assert!(counts.iter().all(|&c| c > 0), "{counts:?}");
    // The negative control: normal agreement alone would leak through.
    assert!(leaks_without_visibility > 0);
}

/// A flat 8 × 8 floor cut into 0.1 cells.
fn floor_scene() -> Scene {
    let mut m = Mesh::default();
    m.rect([-4.0, 0.0, -4.0], [0.0, 0.0, 8.0], [8.0, 0.0, 0.0], 80, 80);
    scene::load(&m.write("meshmap-floor", None)).unwrap()
}

#[test]
fn linear_fields_are_reproduced_with_an_error_that_falls_with_voxel_size() {
    let scene = floor_scene();
    // H(x) = 2 + 0.3 x − 0.2 z: a patch's mean over its area is H at its
    // centre (the area-weighted centroid), so the patch values are exact and
    // the error below is the interpolation's alone.
    let f = |p: [f64; 3]| 2.0 + 0.3 * p[0] - 0.2 * p[2];
    let grad = (0.3f64 * 0.3 + 0.2 * 0.2).sqrt();
    let mut previous_rms = f64::INFINITY;
    for s in [0.5, 0.25, 0.125] {
        let vox = voxelize_at(&scene, s, &Backend::Cpu).unwrap();
        let values: Vec<[f32; 3]> = vox
            .patches
            .iter()
            .map(|p| [f(p.centre) as f32; 3])
            .collect();
        // (rms, max, max inside the centres' hull) of one map.
        let errors = |map: &MeshMap| {
            let h = map.interpolate(&values);
            let (mut sq, mut max, mut max_interior) = (0.0f64, 0.0f64, 0.0f64);
            for (v, hv) in h.iter().enumerate() {
                let p = scene.positions[v].map(f64::from);
                let e = (hv[0] as f64 - f(p)).abs();
                sq += e * e;
                max = max.max(e);
                // Inside the hull of the patch centres (half a voxel from
                // the edge) the weights reproduce linear fields exactly.
                if p[0].abs() <= 4.0 - s / 2.0 && p[2].abs() <= 4.0 - s / 2.0 {
                    max_interior = max_interior.max(e);
                }
            }
            ((sq / h.len() as f64).sqrt(), max, max_interior)
        };
        let map = mesh_map::build(&scene, &vox, &identity(&vox)).unwrap();
        let shepard = mesh_map::build_with(
            &scene,
            &vox,
            &identity(&vox),
            &MeshMapOptions {
                linear_precision: false,
                ..Default::default()
            },
        )
        .unwrap();
        let (rms, max, max_interior) = errors(&map);
        let (rms_s, max_s, max_interior_s) = errors(&shepard);
        println!(
            "voxel {s}: {} patches, {} vertices ({} with full linear precision): error rms \
             {rms:.3e}, max {max:.3e} (|∇H| s = {:.3e}), inside the centres' hull max \
             {max_interior:.3e}; plain Shepard weights: rms {rms_s:.3e}, max {max_s:.3e}, \
             inside max {max_interior_s:.3e}; {:.3} s",
            vox.patches.len(),
            scene.positions.len(),
            map.stats.linear_precision,
            grad * s,
            map.stats.seconds
        );
        // f32 weights and values: a few ulps of |H| ≤ 4.
        assert!(max_interior <= 1e-5, "inside the hull: {max_interior}");
        // ... and the map flags every vertex inside the hull as such.
        let inside = scene
            .positions
            .iter()
            .filter(|p| p[0].abs() as f64 <= 4.0 - s / 2.0 && p[2].abs() as f64 <= 4.0 - s / 2.0)
            .count();
        assert!(map.stats.linear_precision as usize >= inside);
        // At the edge the vertex lies up to s/2 (√2 s/2 at a corner)
        // beyond the last centres and non-negative weights cannot
        // extrapolate: the error is bounded by |∇H| s.
        assert!(max <= grad * s, "max {max} > |∇H| s = {}", grad * s);
        // O(s): with the 0.1 vertex spacing fixed, the edge strip keeps one
        // row of vertices, so rms halves with s (0.6 leaves margin).
        assert!(rms < 0.6 * previous_rms, "rms {rms} vs {previous_rms}");
        // Shepard weights flatten the gradient between centres: an error of
        // order |∇H| s everywhere, which linear precision removes inside
        // the hull (at the edges both extrapolate and err alike).
        assert!(max_interior_s > 0.1 * grad * s, "{max_interior_s}");
        assert!(rms < rms_s, "rms {rms} vs Shepard {rms_s}");
        previous_rms = rms;
        assert_eq!(map.stats.fallbacks + map.stats.unmapped, 0);
    }
}

#[test]
fn removed_patches_are_never_used_and_indices_follow_the_matrix_order() {
    let scene = floor_scene();
    let vox = voxelize_at(&scene, 0.5, &Backend::Cpu).unwrap();
    let n = vox.patches.len();
    // Remove every patch with centre x < 0; number the rest in reverse.
    let kept: Vec<usize> = (0..n).filter(|&i| vox.patches[i].centre[0] > 0.0).collect();
    let mut ids = vec![None; n];
    for (k, &i) in kept.iter().enumerate() {
        ids[i] = Some((kept.len() - 1 - k) as u32);
    }
    let of_matrix: Vec<usize> = (0..kept.len()).map(|m| kept[kept.len() - 1 - m]).collect();
    let map = mesh_map::build(&scene, &vox, &ids).unwrap();
    assert_eq!(check_rows(&scene, &vox, &map, &of_matrix), 0);
    for row in &map.entries {
        for &(p, w) in row {
            assert!(w == 0.0 || (p as usize) < kept.len());
        }
    }
    // Vertices more than 3 voxels from the kept half fall back to the
    // nearest patch facing their side: one patch, weight 1, the nearest.
    let mut far = 0;
    for (v, row) in map.entries.iter().enumerate() {
        let p = scene.positions[v].map(f64::from);
        if p[0] < -3.0 * 0.5 - 0.5 {
            far += 1;
            assert_eq!(row[0].1, 1.0);
            let c = vox.patches[of_matrix[row[0].0 as usize]].centre;
            let d = |c: [f64; 3]| (c[0] - p[0]).powi(2) + (c[2] - p[2]).powi(2);
            let best = kept
                .iter()
                .map(|&i| d(vox.patches[i].centre))
                .fold(f64::INFINITY, f64::min);
            assert!(d(c) <= best + 1e-12, "vertex {v}: not the nearest patch");
        }
    }
    println!("{:?}", map.stats);
    assert!(far > 0);
    assert!(map.stats.fallbacks >= far as u64);
    assert!(map.stats.widened > 0);
}

#[test]
fn a_vertex_with_no_patch_facing_its_side_gets_none() {
    // A floor (+y) and a ceiling (−y) above it; all ceiling patches removed.
    let mut m = Mesh::default();
    m.rect([-1.0, 0.0, -1.0], [0.0, 0.0, 2.0], [2.0, 0.0, 0.0], 4, 4);
    m.rect([-1.0, 1.0, -1.0], [2.0, 0.0, 0.0], [0.0, 0.0, 2.0], 4, 4);
    let scene = scene::load(&m.write("meshmap-unmapped", None)).unwrap();
    // 0.25: at 0.5 the two would be in neighbouring voxel layers and the
    // voxelizer would drop both as covered.
    let vox = voxelize_at(&scene, 0.25, &Backend::Cpu).unwrap();
    let ids: Vec<Option<u32>> = vox
        .patches
        .iter()
        .scan(0u32, |k, p| {
            Some(if p.normal[1] > 0.0 {
                *k += 1;
                Some(*k - 1)
            } else {
                None
            })
        })
        .collect();
    let of_matrix: Vec<usize> = (0..vox.patches.len())
        .filter(|&i| ids[i].is_some())
        .collect();
    let map = mesh_map::build(&scene, &vox, &ids).unwrap();
    let empty = check_rows(&scene, &vox, &map, &of_matrix);
    assert_eq!(empty, 25, "the ceiling's 5 × 5 vertices");
    assert_eq!(map.stats.unmapped, 25);
}

#[test]
fn file_normals_against_the_winding_are_replaced() {
    let mut m = Mesh::default();
    m.rect([-1.0, 0.0, -1.0], [0.0, 0.0, 2.0], [2.0, 0.0, 0.0], 2, 2);
    let down = vec![[0.0, -1.0, 0.0]; m.v.len()];
    let scene = scene::load(&m.write("meshmap-normals", Some(&down))).unwrap();
    let vox = voxelize_at(&scene, 0.5, &Backend::Cpu).unwrap();
    let map = mesh_map::build(&scene, &vox, &identity(&vox)).unwrap();
    assert_eq!(map.stats.file_normals_replaced, 9);
    assert_eq!(map.stats.unmapped + map.stats.fallbacks, 0);
}

/// Maps a bundled or shared scene and checks the invariants; returns the map.
fn map_scene(path: &std::path::Path, voxel: f64) -> (Scene, Voxelization, MeshMap) {
    let scene = scene::load(path).unwrap();
    let t = Instant::now();
    let vox = voxelize_at(&scene, voxel, &Backend::Cpu).unwrap();
    let seconds_vox = t.elapsed().as_secs_f64();
    let map = mesh_map::build(&scene, &vox, &identity(&vox)).unwrap();
    let of_matrix: Vec<usize> = (0..vox.patches.len()).collect();
    assert_eq!(
        check_rows(&scene, &vox, &map, &of_matrix),
        0,
        "every vertex mapped"
    );
    println!(
        "{}: voxel {voxel}, {} triangles, {} patches (voxelized in {seconds_vox:.2} s), \
         mesh map {}",
        path.display(),
        scene.triangles.len(),
        vox.patches.len(),
        serde_json::to_string(&map.stats).unwrap()
    );
    assert_eq!(map.stats.unmapped, 0);
    (scene, vox, map)
}

#[test]
fn cornell_box_every_vertex_is_mapped_deterministically() {
    let (scene, vox, map) = map_scene(&common::bundled("cornell_box"), 20.0);
    // Fallbacks are rare where a vertex can be seen: under 1 % of the
    // vertices. The floor's vertices under the blocks are covered (the
    // voxelizer's rule: inside a solid), in no patch since the floor pieces
    // the blocks' walls cross are cut there (crates/bake/src/cut.rs), so every
    // candidate is behind a wall and they fall back (22 of 1,155).
    let normals = scene.triangle_normals();
    let bvh = Bvh::build(&scene.positions, &scene.triangles, shift_of(&vox.grid));
    let cover = Cover::new(&scene, &vox.grid, &bvh, &normals);
    let hidden = |v: usize| -> bool {
        scene
            .triangles
            .iter()
            .enumerate()
            .filter(|(_, t)| t.contains(&(v as u32)))
            .all(|(k, t)| {
                // The vertex pulled 1 % into the triangle.
                let c: [f64; 3] = std::array::from_fn(|q| {
                    t.iter()
                        .map(|&i| scene.positions[i as usize][q] as f64)
                        .sum::<f64>()
                        / 3.0
                });
                let p = scene.positions[v].map(|x| x as f64);
                let x: [f64; 3] = std::array::from_fn(|q| p[q] + 0.01 * (c[q] - p[q]));
                cover.covered(x, normals[k], k as u32)
            })
    };
    let visible_fallbacks = map
        .outcomes
        .iter()
        .enumerate()
        .filter(|&(v, o)| *o == Outcome::Fallback && !hidden(v))
        .count();
    assert!(
        (visible_fallbacks as f64) < 0.01 * map.stats.vertices as f64,
        "{visible_fallbacks} visible vertices fall back: {:?}",
        map.stats
    );
    let again = mesh_map::build(&scene, &vox, &identity(&vox)).unwrap();
    let bits = |m: &MeshMap| -> Vec<(u32, u32)> {
        m.entries
            .iter()
            .flatten()
            .map(|&(p, w)| (p, w.to_bits()))
            .collect()
    };
    assert_eq!(bits(&map), bits(&again));
}

/// Share of the surface area around vertices that fell back: each
/// triangle gives a third of its area to each of its vertices.
fn fallback_area_share(scene: &Scene, map: &MeshMap) -> f64 {
    let (mut fb, mut total) = (0.0, 0.0);
    for (t, tri) in scene.triangles.iter().enumerate() {
        let a = scene.triangle_area(t) / 3.0;
        for &v in tri {
            total += a;
            if map.outcomes[v as usize] == mesh_map::Outcome::Fallback {
                fb += a;
            }
        }
    }
    fb / total
}

#[test]
fn sponza_every_vertex_is_mapped() {
    let (scene, _, map) = map_scene(&common::sponza(), 0.25);
    let share = fallback_area_share(&scene, &map);
    println!(
        "sponza: {} fallbacks ({:.2} % of vertices, {:.3} % of the area around vertices), \
         {} of them with candidates that were all hidden",
        map.stats.fallbacks,
        100.0 * map.stats.fallbacks as f64 / map.stats.vertices as f64,
        100.0 * share,
        map.stats.fallbacks_blocked
    );
    // Measured 7.3 % of the vertices: Sponza's finely tessellated cornices
    // and balustrades interpenetrate and sit in gaps the 0.25 grid cannot
    // resolve (their own patches were dropped as covered or merged into a
    // neighbour's plane). The bound catches a regression, not the ideal.
    assert!(
        (map.stats.fallbacks as f64) < 0.1 * map.stats.vertices as f64,
        "{:?}",
        map.stats
    );
    assert!(share < 0.05, "{share}");
}
