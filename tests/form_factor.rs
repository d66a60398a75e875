//! Form factors with visibility (`crates/bake/src/form_factor/contour.rs`, `crates/bake/kernels/form_factor.cl`):
//! analytic view factors from Howell's catalog, occlusion with a known
//! answer, the invariants of docs/design.md section 2, OpenCL against the f64
//! CPU reference, determinism, and what the skipping rules save.
//!
//! Plate-level factors are `Σ_{i∈A} A_i Σ_{j∈B} F_ij / Σ_{i∈A} A_i` over
//! the patches of plate A and plate B.

mod common;

use common::{gpu, quad, temp_dir, write_quads, Quad};
use radiosity::bake::form_factor::{self, FormFactorOptions, FormFactors};
use radiosity::bake::voxelize::{self, Voxelization};
use radiosity::core::compute::Backend;
use radiosity::core::npy;
use radiosity::core::patch::Direction;
use radiosity::core::patch::Grid;
use radiosity::core::patch::Patch;
use radiosity::core::scene::{self, Scene};
use radiosity::generate;
use std::path::PathBuf;

/// A bundled scene written fresh into a temp dir (the generator is
/// deterministic, so this is the committed file).
fn generated(name: &str) -> PathBuf {
    let dir = temp_dir(name);
    generate::write_bundled(name, &dir).expect("generating a bundled scene");
    dir.join(format!("{name}.obj"))
}

fn load(path: &std::path::Path, size: f64) -> (Scene, Voxelization) {
    let scene = scene::load(path).expect("loading the scene");
    let vox = voxelize::voxelize_at(&scene, size, &Backend::Cpu).expect("voxelizing");
    (scene, vox)
}

fn run(
    scene: &Scene,
    vox: &Voxelization,
    options: &FormFactorOptions,
    backend: &Backend,
) -> FormFactors {
    form_factor::form_factors(
        scene,
        &vox.patches,
        &vox.grid,
        options,
        backend,
        &mut |_, _| {},
    )
    .expect("form factors")
}

/// Plate-level factor from the patches selected by `a` to those by `b`.
fn plate_factor(
    ff: &FormFactors,
    patches: &[Patch],
    a: impl Fn(&Patch) -> bool,
    b: impl Fn(&Patch) -> bool,
) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (ki, &i) in ff.kept.iter().enumerate() {
        if !a(&patches[i]) {
            continue;
        }
        den += patches[i].area;
        for (kj, &j) in ff.kept.iter().enumerate() {
            if b(&patches[j]) {
                num += patches[i].area * ff.get(ki, kj) as f64;
            }
        }
    }
    num / den
}

fn facing(d: Direction) -> impl Fn(&Patch) -> bool {
    move |p: &Patch| p.direction == d
}

/// Full voxel-face patches tiling the axis-aligned rectangle of the plane
/// `x_a = at` (`a` = `dir`'s axis) with `ranges` along axes `a + 1` and
/// `a + 2` (mod 3), facing `dir`, each in the voxel its normal points into:
/// what the voxelizer makes of a plate, built directly. Used where the
/// voxelizer's neighbour rule would drop patches (it drops a plate's cells
/// whose neighbour voxel holds other geometry, e.g. along every edge where
/// two walls meet), so the form-factor stage is tested on its own.
fn tile(grid: &Grid, dir: Direction, at: f64, ranges: [(f64, f64); 2]) -> Vec<Patch> {
    let (a, s) = (dir.axis(), grid.size);
    let layer = ((at - grid.origin[a]) / s).round() as i64 - i64::from(dir.sign() < 0);
    let (b, c) = ((a + 1) % 3, (a + 2) % 3);
    let cells = |r: (f64, f64)| ((r.1 - r.0) / s).round() as usize;
    let mut out = Vec::new();
    for ib in 0..cells(ranges[0]) {
        for ic in 0..cells(ranges[1]) {
            let mut centre = [0.0; 3];
            centre[a] = at;
            centre[b] = ranges[0].0 + (ib as f64 + 0.5) * s;
            centre[c] = ranges[1].0 + (ic as f64 + 0.5) * s;
            let voxel: [u32; 3] = std::array::from_fn(|k| {
                if k == a {
                    layer as u32
                } else {
                    ((centre[k] - grid.origin[k]) / s).floor() as u32
                }
            });
            out.push(Patch {
                centre,
                normal: dir.vector(),
                area: s * s,
                albedo: [0.5; 3],
                emission: [0.0; 3],
                voxel,
                direction: dir,
            });
        }
    }
    out
}

/// The inward faces of the box `lo..hi` tiled at the grid's voxel size.
fn box_patches(grid: &Grid, lo: [f64; 3], hi: [f64; 3]) -> Vec<Patch> {
    let mut out = Vec::new();
    for a in 0..3 {
        let (b, c) = ((a + 1) % 3, (a + 2) % 3);
        let ranges = [(lo[b], hi[b]), (lo[c], hi[c])];
        out.extend(tile(grid, Direction::ALL[2 * a], lo[a], ranges));
        out.extend(tile(grid, Direction::ALL[2 * a + 1], hi[a], ranges));
    }
    out
}

fn run_on(
    scene: &Scene,
    grid: &Grid,
    patches: &[Patch],
    options: &FormFactorOptions,
    backend: &Backend,
) -> FormFactors {
    form_factor::form_factors(scene, patches, grid, options, backend, &mut |_, _| {})
        .expect("form factors")
}

/// Checks every invariant of docs/design.md section 2 on a result: F ≥ 0,
/// F_ii = 0, reciprocity to 1e-5 relative on every pair (f32 storage of
/// G/A_i and G/A_j: at most 2 f32 roundings, 1.2e-7), row sums ≤ 1 + 1e-6
/// (the correction threshold, plus f32 rounding of the corrected row's
/// entries), and the statistics agree with the matrix.
fn check_invariants(ff: &FormFactors, patches: &[Patch]) {
    let n = ff.n;
    let area = |k: usize| patches[ff.kept[k]].area;
    for i in 0..n {
        assert_eq!(ff.get(i, i), 0.0, "F_ii must be 0");
        for j in 0..n {
            let f = ff.get(i, j);
            assert!(f >= 0.0 && f.is_finite(), "F[{i}][{j}] = {f}");
            if j > i {
                let (a, b) = (area(i) * f as f64, area(j) * ff.get(j, i) as f64);
                let big = a.max(b);
                assert!(
                    (a - b).abs() <= 1e-5 * big,
                    "reciprocity fails for ({i}, {j}): {a} vs {b}"
                );
            }
        }
    }
    let sums = ff.row_sums();
    for (i, s) in sums.iter().enumerate() {
        assert!(*s <= 1.0 + 2e-6, "row {i} sums to {s}");
        assert!(*s > 0.0, "row {i} sees nothing but was kept");
    }
    assert!(ff.stats.max_reciprocity_error <= 1e-5);
    let s = &ff.stats;
    assert_eq!(
        s.pairs_evaluated + s.skipped_backfacing + s.skipped_blocked,
        s.pairs_total,
        "every pair is counted under exactly one rule"
    );
    assert_eq!(s.kept + s.removed_patches, s.patches);
}

/// Howell C-11 (parallel unit squares 1 apart): 0.199825. The plates lie
/// on voxel boundaries, so at voxel size 1/k each is k × k full patches.
#[test]
fn howell_c11_parallel_squares() {
    let path = generated("parallel_squares");
    let exact = generate::parallel_rectangles_factor(1.0, 1.0, 1.0);
    let g = gpu();
    let opts = FormFactorOptions::default();
    println!("C-11 exact {exact:.6}");
    // (At voxel size 1/2 the plates' voxel layers touch and the voxelizer
    // drops both as covered.)
    for size in [0.25, 0.125, 0.0625] {
        let (scene, vox) = load(&path, size);
        let ff = run(&scene, &vox, &opts, &Backend::OpenCl(&g));
        check_invariants(&ff, &vox.patches);
        let f = plate_factor(
            &ff,
            &vox.patches,
            facing(Direction::PosY),
            facing(Direction::NegY),
        );
        let back = plate_factor(
            &ff,
            &vox.patches,
            facing(Direction::NegY),
            facing(Direction::PosY),
        );
        let err = (f - exact) / exact;
        println!(
            "voxel {size}: {} patches, F = {f:.6} (reverse {back:.6}), relative error {err:+.2e}",
            vox.patches.len()
        );
        assert!(
            err.abs() < 0.01,
            "C-11 at voxel size {size}: {f} vs {exact}"
        );
        assert!((back - f).abs() < 1e-6, "equal plates: F_AB = F_BA");
    }
}

/// Howell C-14 (perpendicular unit squares sharing an edge): 0.200044. The
/// patches along the shared edge are adjacent at 90°: this is where
/// point-to-point estimates fail and the exact inner integral matters. The
/// patches are built directly (the voxelizer drops the cells along the
/// shared edge, whose neighbour voxel holds the other plate).
#[test]
fn howell_c14_perpendicular_squares() {
    let scene = scene::load(&generated("perpendicular_squares")).unwrap();
    let exact = generate::perpendicular_rectangles_factor(1.0, 1.0, 1.0);
    let g = gpu();
    let opts = FormFactorOptions::default();
    println!("C-14 exact {exact:.6}");
    for size in [0.25, 0.125, 0.0625] {
        let grid = Grid::new(scene.bounds(), size).unwrap();
        // Emitter y = 0 facing +y (axes z, x), receiver z = 0 facing +z (axes x, y).
        let mut patches = tile(&grid, Direction::PosY, 0.0, [(0.0, 1.0), (0.0, 1.0)]);
        patches.extend(tile(&grid, Direction::PosZ, 0.0, [(0.0, 1.0), (0.0, 1.0)]));
        for backend in [Backend::OpenCl(&g), Backend::Cpu] {
            let ff = run_on(&scene, &grid, &patches, &opts, &backend);
            check_invariants(&ff, &patches);
            let f = plate_factor(
                &ff,
                &patches,
                facing(Direction::PosY),
                facing(Direction::PosZ),
            );
            let err = (f - exact) / exact;
            println!(
                "voxel {size}: {} patches, {}: F = {f:.6}, relative error {err:+.2e}",
                patches.len(),
                ff.stats.backend
            );
            assert!(
                err.abs() < 0.01,
                "C-14 at voxel size {size}: {f} vs {exact}"
            );
        }
    }
}

/// Coaxial unit disks 1 apart: 0.381966 for true disks. The scene's
/// 128-gons have 0.04 % less area; the rim patches are partial voxels whose
/// squares only approximate their shape (area and centroid kept), an error
/// that falls with the voxel size.
#[test]
fn coaxial_disks() {
    let path = generated("coaxial_disks");
    let exact = generate::coaxial_disks_factor(1.0, 1.0, 1.0);
    let g = gpu();
    let opts = FormFactorOptions::default();
    println!("coaxial disks exact {exact:.6}");
    for size in [0.25, 0.125] {
        let (scene, vox) = load(&path, size);
        let ff = run(&scene, &vox, &opts, &Backend::OpenCl(&g));
        check_invariants(&ff, &vox.patches);
        let f = plate_factor(
            &ff,
            &vox.patches,
            facing(Direction::PosY),
            facing(Direction::NegY),
        );
        let err = (f - exact) / exact;
        println!(
            "voxel {size}: {} patches, F = {f:.6}, relative error {err:+.2e}",
            vox.patches.len()
        );
        assert!(
            err.abs() < 0.01,
            "coaxial disks at voxel size {size}: {f} vs {exact}"
        );
    }
}

const GREY: [f64; 3] = [0.5; 3];
const X: [f64; 3] = [1.0, 0.0, 0.0];
const Y: [f64; 3] = [0.0, 1.0, 0.0];
const Z: [f64; 3] = [0.0, 0.0, 1.0];

/// The C-11 plates (y = 0 facing +y, y = 1 facing −y, x, z ∈ [0, 1]) plus
/// extra quads.
fn plates_with(extra: &[Quad]) -> Vec<Quad> {
    // quad(c, u, v, ..) faces u × v: z × x = +y, x × z = −y.
    let mut q = vec![
        quad([0.5, 0.0, 0.5], Z, X, 0.5, 0.5, GREY),
        quad([0.5, 1.0, 0.5], X, Z, 0.5, 0.5, GREY),
    ];
    q.extend_from_slice(extra);
    q
}

/// An occluder at y = 0.5 covering x < 0.5 (far beyond the plates in the
/// other directions). A segment from (x_a, 0, ·) to (x_b, 1, ·) crosses the
/// midplane at x = (x_a + x_b)/2, so it is blocked iff x_a + x_b < 1; the
/// reflection x → 1 − x of both plates preserves the integrand and swaps
/// blocked and open segments, so exactly half of F is blocked:
/// F = 0.199825 / 2, independently of any sampling. A full occluder gives 0.
#[test]
fn occluders_block_the_expected_fraction() {
    let exact = generate::parallel_rectangles_factor(1.0, 1.0, 1.0);
    let g = gpu();
    let opts = FormFactorOptions::default();
    // Double-sided (a quad facing +y, z × x, and one facing −y, x × z), so
    // the plates see it; the half occluder spans x ∈ [−1.5, 0.5].
    let half = [
        quad([-0.5, 0.5, 0.5], Z, X, 2.0, 1.0, GREY),
        quad([-0.5, 0.5, 0.5], X, Z, 1.0, 2.0, GREY),
    ];
    let full = [
        quad([0.5, 0.5, 0.5], Z, X, 2.0, 2.0, GREY),
        quad([0.5, 0.5, 0.5], X, Z, 2.0, 2.0, GREY),
    ];
    // At voxel size 1/8 an empty voxel layer separates the plates from the
    // occluder (at 1/4 the voxelizer would drop the plate cells under it as
    // covered).
    let plates = |p: &Patch| p.centre[1] < 0.25 || p.centre[1] > 0.75;
    let bottom = |p: &Patch| p.direction == Direction::PosY && p.centre[1] < 0.25;
    let top = |p: &Patch| p.direction == Direction::NegY && p.centre[1] > 0.75;
    for backend in [Backend::OpenCl(&g), Backend::Cpu] {
        let (scene, vox) = load(&write_quads("half", &plates_with(&half)), 0.125);
        let ff = run(&scene, &vox, &opts, &backend);
        check_invariants(&ff, &vox.patches);
        let f = plate_factor(&ff, &vox.patches, bottom, top);
        let err = (f - exact / 2.0) / (exact / 2.0);
        println!(
            "half occluder: F = {f:.6}, expected {:.6}, relative error {err:+.2e}",
            exact / 2.0
        );
        assert!(err.abs() < 0.01, "half occluder: {f} vs {}", exact / 2.0);
        assert_eq!(vox.patches.iter().filter(|p| plates(p)).count(), 128);

        let (scene, vox) = load(&write_quads("full", &plates_with(&full)), 0.125);
        let ff = run(&scene, &vox, &opts, &backend);
        check_invariants(&ff, &vox.patches);
        let f = plate_factor(&ff, &vox.patches, bottom, top);
        println!("full occluder: F = {f}, stats:\n{}", ff.stats);
        assert_eq!(f, 0.0, "a full occluder blocks everything");
        // 64 × 64 plate pairs; every one is blocked by the occluder quad,
        // which is one certificate polygon: each costs one ray.
        assert!(
            ff.stats.skipped_blocked >= 4096,
            "{}",
            ff.stats.skipped_blocked
        );
    }
}

/// The closed unit cube: every row of F sums to 1 (within 0.1 %): the
/// squares of the 6 k² patches tile the cube, each sample's inner
/// integrals sum to exactly 1, and only the midpoint rule's error remains.
/// The patches are built directly (the voxelizer drops the cells along the
/// cube's edges).
#[test]
fn closed_cube_rows_sum_to_one() {
    let scene = scene::load(&generated("closed_cube")).unwrap();
    let g = gpu();
    for size in [0.25, 0.125] {
        let grid = Grid::new(scene.bounds(), size).unwrap();
        let patches = box_patches(&grid, [0.0; 3], [1.0; 3]);
        let ff = run_on(
            &scene,
            &grid,
            &patches,
            &FormFactorOptions::default(),
            &Backend::OpenCl(&g),
        );
        check_invariants(&ff, &patches);
        let sums = ff.row_sums();
        let (lo, hi) = sums
            .iter()
            .fold((f64::MAX, 0.0f64), |(a, b), &s| (a.min(s), b.max(s)));
        println!(
            "voxel {size}: {} patches, row sums in [{lo:.6}, {hi:.6}], max before corrections {:.6}, {} corrections\n{}",
            ff.n, ff.stats.max_row_sum_before, ff.stats.row_corrections, ff.stats
        );
        assert_eq!(ff.n, patches.len());
        assert_eq!(ff.stats.skipped_blocked, 0);
        for (i, s) in sums.iter().enumerate() {
            assert!((s - 1.0).abs() < 1e-3, "row {i} sums to {s}");
        }
    }
}

/// OpenCL (f32) against the CPU reference (f64) on the same prepared input.
///
/// Tolerance, per pair: the inner (Lambert) sum of a far pair cancels terms
/// of size `side/r` down to a result of size `(side/r)²`, so its f32
/// relative error is about `u · (r/side) · k` with `u = 6e-8` and `k` ~ 10
/// operations per term; with `r/side` ≤ 30 in these scenes that is ~2e-5,
/// and coordinates relative to the grid centre add `u · L/r` ≤ ~1e-6. We
/// allow 1e-4 relative plus 1e-7 absolute. A visibility ray within rounding
/// of a triangle edge may flip between the paths and change one sample by
/// one ray's share: allowed for at most 0.5 % of the pairs, and row sums
/// must still agree to 1e-3.
#[test]
fn opencl_matches_cpu_reference() {
    let g = gpu();
    let opts = FormFactorOptions::default();
    for (name, size) in [("closed_cube", 0.125), ("cornell_box", 70.0)] {
        let scene = scene::load(&generated(name)).unwrap();
        let (grid, patches) = if name == "closed_cube" {
            let grid = Grid::new(scene.bounds(), size).unwrap();
            (grid, box_patches(&grid, [0.0; 3], [1.0; 3]))
        } else {
            let vox = voxelize::voxelize_at(&scene, size, &Backend::Cpu).unwrap();
            (vox.grid, vox.patches)
        };
        let cl = run_on(&scene, &grid, &patches, &opts, &Backend::OpenCl(&g));
        let cpu = run_on(&scene, &grid, &patches, &opts, &Backend::Cpu);
        check_invariants(&cl, &patches);
        check_invariants(&cpu, &patches);
        let c = form_factor::compare(&cl, &cpu).unwrap();
        println!(
            "{name} at {size}: {} patches\nOpenCL: {}CPU: {}{c:?}",
            patches.len(),
            cl.stats,
            cpu.stats
        );
        // The discrete decisions are taken in f32 by both paths.
        assert_eq!(cl.stats.skipped_backfacing, cpu.stats.skipped_backfacing);
        let pairs = cl.stats.pairs_total as f64;
        assert!(
            (c.entries_beyond_1e4 as f64) <= 0.005 * 2.0 * pairs,
            "{} entries differ beyond the f32 tolerance",
            c.entries_beyond_1e4
        );
        assert!(
            c.max_row_sum_diff < 1e-3,
            "row sums differ by {}",
            c.max_row_sum_diff
        );
        if name == "closed_cube" {
            // Nothing occludes inside the cube: no ray can flip.
            assert_eq!(c.entries_beyond_1e4, 0);
            assert_eq!(cl.stats.rays_cast, cpu.stats.rays_cast);
        }
    }
}

/// Reciprocity, row sums, F ≥ 0 on the Cornell box with its blocks.
#[test]
fn invariants_on_the_cornell_box() {
    let g = gpu();
    let (scene, vox) = load(&generated("cornell_box"), 50.0);
    let ff = run(
        &scene,
        &vox,
        &FormFactorOptions::default(),
        &Backend::OpenCl(&g),
    );
    println!("{} patches\n{}", vox.patches.len(), ff.stats);
    check_invariants(&ff, &vox.patches);
    assert!(ff.stats.skipped_backfacing > 0);
    assert!(ff.stats.pairs_evaluated > 0);
}

/// Same input and options, same bytes: OpenCL twice, CPU twice, and a
/// different batch size (batches must not change results).
#[test]
fn deterministic() {
    let g = gpu();
    let (scene, vox) = load(&generated("cornell_box"), 70.0);
    let opts = FormFactorOptions::default();
    let a = run(&scene, &vox, &opts, &Backend::OpenCl(&g));
    let b = run(&scene, &vox, &opts, &Backend::OpenCl(&g));
    let small = FormFactorOptions {
        batch_seconds: 0.01,
        ..opts.clone()
    };
    let c = run(&scene, &vox, &small, &Backend::OpenCl(&g));
    assert!(
        c.stats.batches > a.stats.batches,
        "{} vs {}",
        c.stats.batches,
        a.stats.batches
    );
    let bits = |f: &FormFactors| f.f.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a), bits(&b));
    assert_eq!(bits(&a), bits(&c));
    assert_eq!(a.kept, b.kept);
    let d = run(&scene, &vox, &opts, &Backend::Cpu);
    let e = run(&scene, &vox, &opts, &Backend::Cpu);
    assert_eq!(bits(&d), bits(&e));
}

/// A plate facing into empty space sees nothing: its patches are removed,
/// counted, and left out of `kept`.
#[test]
fn isolated_patches_are_removed_and_counted() {
    let g = gpu();
    // A third square below the bottom plate, facing −y, away from everything.
    let lonely = quad([0.5, -2.0, 0.5], X, Z, 0.5, 0.5, GREY);
    let (scene, vox) = load(&write_quads("lonely", &plates_with(&[lonely])), 0.25);
    let ff = run(
        &scene,
        &vox,
        &FormFactorOptions::default(),
        &Backend::OpenCl(&g),
    );
    check_invariants(&ff, &vox.patches);
    let lonely_ids: Vec<usize> = (0..vox.patches.len())
        .filter(|&i| vox.patches[i].centre[1] < -1.0)
        .collect();
    assert_eq!(lonely_ids.len(), 16);
    assert_eq!(ff.stats.removed_patches, 16);
    assert_eq!(ff.n, vox.patches.len() - 16);
    assert!(lonely_ids.iter().all(|i| !ff.kept.contains(i)));
    println!("{}", ff.stats);
}

/// Back-facing pairs cost nothing: two plates back to back (facing away
/// from each other) have no pair evaluated and no ray cast; every patch
/// sees nothing and is removed. In C-11, the coplanar pairs inside each
/// plate are exactly the back-facing ones, and rays are cast only for the
/// evaluated pairs.
#[test]
fn back_facing_pairs_cost_nothing() {
    let g = gpu();
    let back_to_back = [
        quad([0.5, 0.0, 0.5], X, Z, 0.5, 0.5, GREY),  // faces −y
        quad([0.5, 0.25, 0.5], Z, X, 0.5, 0.5, GREY), // faces +y
    ];
    let (scene, vox) = load(&write_quads("b2b", &back_to_back), 0.25);
    for backend in [Backend::OpenCl(&g), Backend::Cpu] {
        let ff = run(&scene, &vox, &FormFactorOptions::default(), &backend);
        let n = vox.patches.len() as u64;
        assert_eq!(n, 32);
        assert_eq!(ff.stats.skipped_backfacing, n * (n - 1) / 2);
        assert_eq!(ff.stats.pairs_evaluated, 0);
        assert_eq!(ff.stats.rays_cast, 0);
        assert_eq!(ff.stats.removed_patches, n);
        assert_eq!(ff.n, 0);
    }
    let (scene, vox) = load(&generated("parallel_squares"), 0.25);
    let ff = run(
        &scene,
        &vox,
        &FormFactorOptions::default(),
        &Backend::OpenCl(&g),
    );
    // 2 plates of 16 coplanar patches: 2 · C(16, 2) back-facing pairs, and
    // the 256 opposed pairs evaluated (2 × 2 nodes × 1 ray each).
    assert_eq!(ff.stats.skipped_backfacing, 2 * 120);
    assert_eq!(ff.stats.pairs_evaluated, 256);
    assert_eq!(ff.stats.rays_cast, 256 * 4);
}

/// Two closed rooms side by side: no light crosses the walls, and pairs
/// across them are proven blocked after one ray each by the walls' quad
/// certificates, instead of being evaluated with every ray.
#[test]
fn disconnected_rooms_are_cheap() {
    let g = gpu();
    // Room k: the box [2k, 2k + 1] × [0, 1] × [0, 1], faces inwards.
    let mut quads = Vec::new();
    for k in 0..2 {
        let x0 = 2.0 * k as f64;
        let c = [x0 + 0.5, 0.5, 0.5];
        let at = |d: [f64; 3]| [c[0] + 0.5 * d[0], c[1] + 0.5 * d[1], c[2] + 0.5 * d[2]];
        // Inward normal = −d; quad(u, v) faces u × v.
        quads.push(quad(at([1.0, 0.0, 0.0]), Z, Y, 0.5, 0.5, GREY)); // faces −x
        quads.push(quad(at([-1.0, 0.0, 0.0]), Y, Z, 0.5, 0.5, GREY)); // faces +x
        quads.push(quad(at([0.0, 1.0, 0.0]), X, Z, 0.5, 0.5, GREY)); // faces −y
        quads.push(quad(at([0.0, -1.0, 0.0]), Z, X, 0.5, 0.5, GREY)); // faces +y
        quads.push(quad(at([0.0, 0.0, 1.0]), Y, X, 0.5, 0.5, GREY)); // faces −z
        quads.push(quad(at([0.0, 0.0, -1.0]), X, Y, 0.5, 0.5, GREY)); // faces +z
    }
    let scene = scene::load(&write_quads("rooms", &quads)).unwrap();
    let grid = Grid::new(scene.bounds(), 0.25).unwrap();
    let mut patches = box_patches(&grid, [0.0; 3], [1.0; 3]);
    patches.extend(box_patches(&grid, [2.0, 0.0, 0.0], [3.0, 1.0, 1.0]));
    assert_eq!(patches.len(), 192);
    let room = |p: &Patch| usize::from(p.centre[0] > 1.5);
    for certificates in [true, false] {
        let opts = FormFactorOptions {
            certificates,
            ..Default::default()
        };
        let ff = run_on(&scene, &grid, &patches, &opts, &Backend::OpenCl(&g));
        check_invariants(&ff, &patches);
        let cross = plate_factor(&ff, &patches, |p| room(p) == 0, |p| room(p) == 1);
        println!(
            "certificates {certificates}: cross-room F = {cross}\n{}",
            ff.stats
        );
        assert_eq!(cross, 0.0, "light crossed a wall");
        for s in ff.row_sums() {
            assert!((s - 1.0).abs() < 1e-3, "a room is closed: row sum {s}");
        }
        if certificates {
            // Cross-room pairs that face each other: most are certified
            // after one ray.
            assert!(
                ff.stats.skipped_blocked > 4000,
                "{}",
                ff.stats.skipped_blocked
            );
            assert!(ff.stats.evaluated_zero < ff.stats.skipped_blocked / 4);
        }
    }
}

/// `write_f_npy` writes what `npy::read_f32` (and numpy) reads, and refuses
/// matrices above the documented limit before allocating anything.
#[test]
fn npy_export() {
    let g = gpu();
    let (scene, vox) = load(&generated("parallel_squares"), 0.5);
    let ff = run(
        &scene,
        &vox,
        &FormFactorOptions::default(),
        &Backend::OpenCl(&g),
    );
    let dir = temp_dir("npy");
    let p = dir.join("F.npy");
    form_factor::write_f_npy(&p, &ff).unwrap();
    let (shape, data) = npy::read_f32(&p).unwrap();
    assert_eq!(shape, vec![ff.n, ff.n]);
    assert_eq!(data, ff.f);
    let huge = FormFactors {
        n: 23171,
        f: Vec::new(),
        kept: Vec::new(),
        sky: Vec::new(),
        stats: Default::default(),
    };
    let err = form_factor::write_f_npy(&p, &huge).unwrap_err().to_string();
    assert!(err.contains("limit"), "{err}");
}

/// Options are validated with clear messages.
#[test]
fn options_are_validated() {
    let ok = FormFactorOptions::default();
    assert!(ok.validate().is_ok());
    for bad in [
        FormFactorOptions {
            samples: 0,
            ..ok.clone()
        },
        FormFactorOptions {
            samples: 17,
            ..ok.clone()
        },
        FormFactorOptions {
            rays: 0,
            ..ok.clone()
        },
        FormFactorOptions {
            quadrature_tol: 0.0,
            ..ok.clone()
        },
        FormFactorOptions {
            batch_seconds: f64::NAN,
            ..ok.clone()
        },
    ] {
        let e = bad.validate().unwrap_err().to_string();
        assert!(e.contains("form-factor"), "{e}");
    }
}
