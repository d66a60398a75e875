//! Tests of the reordering (crates/bake/src/reorder.rs and crates/bake/kernels/reorder.cl): the
//! permutation's algebra, the Hilbert curve, the OpenCL distance kernel
//! against the f64 CPU reference, and what the greedy chain recovers.

mod common;

use radiosity::bake::encode;
use radiosity::bake::reorder::{self, Features, ReorderMethod};

use radiosity::bakefile::codec::{self, CodecKind, SparseValues};
use radiosity::core::compute::Backend;
use radiosity::core::permutation::Permutation;
use radiosity::synthetic;

/// A seeded random permutation of `n` (Fisher–Yates).
fn shuffle(n: usize, seed: u64) -> Permutation {
    let mut rng = synthetic::Rng(seed);
    let mut order: Vec<u32> = (0..n as u32).collect();
    for i in (1..n).rev() {
        let j = (rng.next_u64() % (i as u64 + 1)) as usize;
        order.swap(i, j);
    }
    Permutation::from_order(order).unwrap()
}

/// A smooth three-channel kernel matrix over points on a line at seeded
/// random, distinct positions (so that nearest-neighbour distances have no
/// ties): `T_c(i, j) = s_c e^{−|x_i − x_j| / 0.05}`. In position order its
/// rows change smoothly; the positions are returned too.
fn smooth_line_matrix(n: usize, seed: u64) -> ([Vec<f32>; 3], Vec<f64>) {
    let mut rng = synthetic::Rng(seed);
    let mut x: Vec<f64> = (0..n)
        .map(|i| (i as f64 + 0.2 + 0.6 * rng.uniform()) / n as f64)
        .collect();
    x.sort_by(f64::total_cmp);
    let t = std::array::from_fn(|c| {
        let s = [1.0, 0.8, 0.6][c];
        (0..n * n)
            .map(|k| (s * (-(x[k / n] - x[k % n]).abs() / 0.05).exp()) as f32)
            .collect()
    });
    (t, x)
}

fn refs(t: &[Vec<f32>; 3]) -> [&[f32]; 3] {
    [&t[0][..], &t[1][..], &t[2][..]]
}

fn permuted(p: &Permutation, t: &[Vec<f32>; 3], n: usize) -> [Vec<f32>; 3] {
    std::array::from_fn(|c| p.apply_symmetric(&t[c], n))
}

#[test]
fn permutation_round_trip_keeps_the_product() {
    let patches = synthetic::room(6, 2);
    let n = patches.len();
    let f = synthetic::form_factors(&patches);
    let t = synthetic::transfer_rgb(&patches, &f);
    let b0 = synthetic::point_lights(&patches, 1, 3).remove(0);
    let p = shuffle(n, 11);
    let tp = permuted(&p, &t, n);
    // Back with the inverse permutation: bit for bit.
    let back = Permutation::from_order(p.inverse.clone()).unwrap();
    for c in 0..3 {
        assert_eq!(back.apply_symmetric(&tp[c], n), t[c]);
        assert_eq!(p.unapply_vec(&p.apply_vec(&b0[c])), b0[c]);
    }
    // (P T Pᵀ)(P b) = P (T b): the f32 products are exact in f64, so only
    // the f64 summation order differs (≤ n 2^-53 relative).
    for c in 0..3 {
        let h = encode::mat_vec(&t[c], n, &b0[c]);
        let hp = encode::mat_vec(&tp[c], n, &p.apply_vec(&b0[c]));
        let h_back = p.unapply_vec(&hp);
        for (a, b) in h.iter().zip(&h_back) {
            assert!((a - b).abs() <= 1e-12 * a.abs(), "{a} vs {b}");
        }
    }
    // Through the exact codec and the run-time gather: the same up to the
    // f32 summation order (each entry within (n + 1) 2^-24 of Σ|T||b|).
    let e = encode::encode(CodecKind::F32, refs(&tp), n).unwrap();
    let bp: [Vec<f32>; 3] = std::array::from_fn(|c| p.apply_vec(&b0[c]));
    let g = e.gather(refs(&bp));
    for c in 0..3 {
        let g_back = p.unapply_vec(&g[c]);
        let abs: Vec<f64> = (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| (t[c][i * n + j] * b0[c][j]).abs() as f64)
                    .sum()
            })
            .collect();
        let h = encode::mat_vec(&t[c], n, &b0[c]);
        for i in 0..n {
            let tol = (n + 1) as f64 * 2f64.powi(-24) * abs[i];
            assert!((g_back[i] as f64 - h[i]).abs() <= tol, "row {i}");
        }
    }
    // Composition.
    let q = shuffle(n, 12);
    let pq = p.then(&q);
    let v: Vec<u32> = (0..n as u32).collect();
    assert_eq!(pq.apply_vec(&v), q.apply_vec(&p.apply_vec(&v)));
}

#[test]
fn from_order_rejects_non_permutations() {
    assert!(Permutation::from_order(vec![0, 1, 1]).is_err());
    assert!(Permutation::from_order(vec![0, 3, 1]).is_err());
    let p = Permutation::from_order(vec![2, 0, 1]).unwrap();
    assert_eq!(p.inverse, vec![1, 2, 0]);
    assert_eq!(Permutation::identity(3).order, vec![0, 1, 2]);
}

#[test]
fn hilbert_curve_visits_every_cell_through_neighbours() {
    // The defining property: consecutive indices are face neighbours, and
    // every cell of the 2^b cube has exactly one index.
    let bits = 3;
    let side = 1u32 << bits;
    let mut cells = vec![None; (side * side * side) as usize];
    for x in 0..side {
        for y in 0..side {
            for z in 0..side {
                let h = reorder::hilbert_index([x, y, z], bits) as usize;
                assert!(cells[h].is_none(), "index {h} used twice");
                cells[h] = Some([x, y, z]);
            }
        }
    }
    for w in cells.windows(2) {
        let (a, b) = (w[0].unwrap(), w[1].unwrap());
        let manhattan: u32 = (0..3).map(|k| a[k].abs_diff(b[k])).sum();
        assert_eq!(manhattan, 1, "{a:?} -> {b:?}");
    }
}

#[test]
fn hilbert_order_groups_directions_and_keeps_neighbours_close() {
    let patches = synthetic::room(8, 2);
    let n = patches.len();
    let t = [vec![0.0f32; n * n], vec![0.0; n * n], vec![0.0; n * n]];
    let (p, stats) = reorder::reorder_with_stats(
        ReorderMethod::SpaceFillingCurve,
        refs(&t),
        n,
        &patches,
        Backend::Cpu,
    )
    .unwrap();
    let dirs: Vec<u8> = p
        .order
        .iter()
        .map(|&i| patches[i as usize].direction as u8)
        .collect();
    assert!(
        dirs.windows(2).all(|w| w[0] <= w[1]),
        "directions are not grouped"
    );
    // Within a direction, consecutive patches are mostly face neighbours:
    // the mean step is below 1.5 voxel edges (1/8 here).
    let mut steps = Vec::new();
    for w in p.order.windows(2) {
        let (a, b) = (&patches[w[0] as usize], &patches[w[1] as usize]);
        if a.direction == b.direction {
            let d: f64 = (0..3)
                .map(|k| (a.centre[k] - b.centre[k]).powi(2))
                .sum::<f64>()
                .sqrt();
            steps.push(d * 8.0);
        }
    }
    let mean = steps.iter().sum::<f64>() / steps.len() as f64;
    assert!(mean < 1.5, "mean step {mean} voxels");
    assert_eq!(stats.method, "hilbert");
}

#[test]
fn opencl_distances_match_the_cpu_reference() {
    let gpu = common::gpu();
    // n and d not multiples of the work-group tile; smooth-ish features
    // with some identical rows (distance exactly 0).
    let n = 150;
    let d = 3 * n;
    let mut rng = synthetic::Rng(5);
    let mut x: Vec<f32> = (0..n * d).map(|_| rng.uniform() as f32).collect();
    let (src, dst) = (7 * d, 8 * d);
    x.copy_within(src..src + d, dst);
    let cpu = reorder::cpu_distances(&x, n, d);
    // A small output budget forces several batches.
    let (cl, _) = reorder::cl_distances_batched(&gpu, &x, n, d, (n * 4 * 32) as u64).unwrap();
    let (cl_one, secs) = reorder::cl_distances(&gpu, &x, n, d).unwrap();
    assert_eq!(cl, cl_one, "batching changed the result");
    assert!(secs >= 0.0);
    for i in 0..n {
        for k in 0..n {
            // Brute force in f64: the reference of both.
            let exact: f64 = (0..d)
                .map(|c| (x[i * d + c] as f64 - x[k * d + c] as f64).powi(2))
                .sum();
            let (a, b) = (cl[i * n + k] as f64, cpu[i * n + k] as f64);
            // The kernel sums d non-negative f32 terms: relative error
            // below (d + 2) 2^-24. The Gram form in f64 errs by about
            // d 2^-53 (|x_i|² + |x_k|²) absolutely.
            let norms: f64 = (0..d)
                .map(|c| (x[i * d + c] as f64).powi(2) + (x[k * d + c] as f64).powi(2))
                .sum();
            assert!(
                (a - exact).abs() <= (d + 2) as f64 * 2f64.powi(-24) * exact,
                "cl ({i},{k}): {a} vs {exact}"
            );
            assert!(
                (b - exact).abs() <= 1e-7 * exact + d as f64 * 2f64.powi(-50) * norms,
                "cpu ({i},{k}): {b} vs {exact}"
            );
            assert_eq!(cl[i * n + k], cl[k * n + i], "not symmetric");
        }
    }
    assert_eq!(cl[7 * n + 8], 0.0);
}

/// Fraction of consecutive rows in `order` that are neighbours on the line.
fn neighbour_fraction(order: &[u32]) -> f64 {
    let hits = order
        .windows(2)
        .filter(|w| w[0].abs_diff(w[1]) == 1)
        .count();
    hits as f64 / (order.len() - 1) as f64
}

#[test]
fn greedy_recovers_a_shuffled_smooth_matrix_and_helps_bc1() {
    let n = 192;
    let (t, _) = smooth_line_matrix(n, 9);
    let shuffle = shuffle(n, 21);
    let ts = permuted(&shuffle, &t, n);
    let patches = Vec::new();
    let (p, stats) = reorder::reorder_with_stats(
        ReorderMethod::Greedy { passes: 2 },
        refs(&ts),
        n,
        &patches,
        Backend::Cpu,
    )
    .unwrap();
    // In the original labels: nearly in order (each row's nearest
    // neighbour is an adjacent point; the chain may turn back once).
    let recovered = shuffle.then(&p);
    let frac = neighbour_fraction(&recovered.order);
    assert!(
        frac >= 0.97,
        "only {frac} of consecutive rows are neighbours"
    );
    assert!(stats.adjacent_distance_after < 0.2 * stats.adjacent_distance_before);
    assert!(
        stats.chain_lengths.windows(2).all(|w| w[1] <= w[0]),
        "2-opt lengthened the chain"
    );

    // BC1 on the shuffled matrix against the greedy-reordered one.
    let kind = CodecKind::Bc1Log {
        top_fraction: 0.0,
        log_range: codec::LOG_RANGE_AUTO,
        sparse: SparseValues::F16,
    };
    let tg = permuted(&p, &ts, n);
    let err = |m: &[Vec<f32>; 3]| {
        let e = encode::encode(kind, refs(m), n).unwrap();
        encode::measure(refs(m), n, &e.decode(), &[]).rel_frobenius
    };
    let (shuffled, reordered) = (err(&ts), err(&tg));
    eprintln!("neighbour fraction {frac}, BC1 rel. Frobenius {shuffled:.3e} shuffled, {reordered:.3e} greedy");
    assert!(
        reordered < 0.5 * shuffled,
        "BC1 error {reordered} after greedy vs {shuffled} shuffled"
    );
}

#[test]
fn greedy_on_opencl_matches_the_cpu() {
    let gpu = common::gpu();
    let n = 160;
    let (t, _) = smooth_line_matrix(n, 4);
    let ts = permuted(&shuffle(n, 8), &t, n);
    let cpu = reorder::reorder(
        ReorderMethod::Greedy { passes: 2 },
        refs(&ts),
        n,
        &[],
        Backend::Cpu,
    )
    .unwrap();
    let (cl, stats) = reorder::reorder_with_stats(
        ReorderMethod::Greedy { passes: 2 },
        refs(&ts),
        n,
        &[],
        Backend::OpenCl(&gpu),
    )
    .unwrap();
    assert_eq!(cpu, cl);
    assert!(stats.kernel_seconds > 0.0);
}

#[test]
fn grey_input_uses_one_channel_and_the_same_order() {
    let n = 96;
    let (t, _) = smooth_line_matrix(n, 2);
    let ts = permuted(&shuffle(n, 3), &t, n);
    let grey = [&ts[0][..], &ts[0][..], &ts[0][..]];
    assert_eq!(radiosity::bakefile::codec::distinct_channels(grey).len(), 1);
    let f = Features::new(&radiosity::bakefile::codec::distinct_channels(grey), n);
    assert_eq!(f.dim(), n);
    let p1 = reorder::reorder(
        ReorderMethod::Greedy { passes: 1 },
        grey,
        n,
        &[],
        Backend::Cpu,
    )
    .unwrap();
    // A colour matrix whose channels are multiples of one another has the
    // same log features up to a constant per channel: the same order.
    let scaled: [Vec<f32>; 3] =
        std::array::from_fn(|c| ts[0].iter().map(|v| v * [1.0, 0.5, 0.25][c]).collect());
    let p3 = reorder::reorder(
        ReorderMethod::Greedy { passes: 1 },
        refs(&scaled),
        n,
        &[],
        Backend::Cpu,
    )
    .unwrap();
    assert_eq!(p1, p3);
}

#[test]
fn bad_input_is_an_error() {
    let n = 4;
    let t = vec![0.0f32; n * n];
    let r = [&t[..], &t[..], &t[..]];
    assert!(
        reorder::reorder(ReorderMethod::Greedy { passes: 0 }, r, n, &[], Backend::Cpu).is_err()
    );
    let err =
        reorder::reorder(ReorderMethod::SpaceFillingCurve, r, n, &[], Backend::Cpu).unwrap_err();
    assert!(err.to_string().contains("patches"), "{err}");
    assert!(reorder::reorder(ReorderMethod::None, r, 5, &[], Backend::Cpu).is_err());
    assert_eq!(
        reorder::reorder(ReorderMethod::None, r, n, &[], Backend::Cpu).unwrap(),
        Permutation::identity(n)
    );
    for (s, m) in [
        ("none", ReorderMethod::None),
        ("greedy", ReorderMethod::Greedy { passes: 2 }),
        ("greedy:3", ReorderMethod::Greedy { passes: 3 }),
        ("hilbert", ReorderMethod::SpaceFillingCurve),
    ] {
        assert_eq!(ReorderMethod::parse(s).unwrap(), m);
        assert_eq!(ReorderMethod::parse(&m.name()).unwrap(), m);
    }
    assert!(ReorderMethod::parse("greedy:0").is_err());
    assert!(ReorderMethod::parse("spectral").is_err());
}
