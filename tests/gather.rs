//! The run time's compressed gather (crates/runtime/src/gather.rs) against the
//! codec's reference decode and the exact product, for every codec, with
//! and without AVX-512 and column skipping.

use radiosity::bake::encode;
use radiosity::bake::reorder;
use radiosity::bakefile::codec::{
    CodecKind, DenseFormat, Encoded, SparseValues, TileIndex, LOG_RANGE_AUTO,
};
use radiosity::runtime::gather::{dense_product, simd_available, ActiveColumns, CompressedGather};
use radiosity::synthetic;

fn refs(t: &[Vec<f32>; 3]) -> [&[f32]; 3] {
    [&t[0][..], &t[1][..], &t[2][..]]
}

/// The synthetic room's T_∞ in Hilbert order, and a B0 lit by one point
/// light (zero where the light does not reach: whole column groups).
fn problem(m: usize, b: usize, grey: bool) -> ([Vec<f32>; 3], [Vec<f32>; 3], usize) {
    let mut patches = synthetic::room(m, b);
    if grey {
        for p in &mut patches {
            p.albedo = [0.7; 3];
        }
    }
    let n = patches.len();
    let f = synthetic::form_factors(&patches);
    let t = synthetic::transfer_rgb(&patches, &f);
    let p = reorder::hilbert_order(&patches);
    let t: [Vec<f32>; 3] = std::array::from_fn(|c| p.apply_symmetric(&t[c], n));
    let mut b0 = synthetic::point_lights(&patches, 1, 7).remove(0);
    for c in &mut b0 {
        *c = p.apply_vec(c);
        // A spot-like light: only the patches in the first third lit.
        for (j, v) in c.iter_mut().enumerate() {
            if j % 3 != 0 || j > n / 2 {
                *v = 0.0;
            }
        }
    }
    (t, b0, n)
}

fn kinds() -> Vec<(&'static str, CodecKind)> {
    vec![
        ("bc1 default", CodecKind::default()),
        (
            "bc1 f16 sparse",
            CodecKind::Bc1Log {
                top_fraction: 0.02,
                log_range: LOG_RANGE_AUTO,
                sparse: SparseValues::F16,
            },
        ),
        (
            "bc1 no sparse",
            CodecKind::Bc1Log {
                top_fraction: 0.0,
                log_range: 25.0,
                sparse: SparseValues::F32,
            },
        ),
        (
            "bc4",
            CodecKind::Bc4Log {
                top_fraction: 0.02,
                log_range: LOG_RANGE_AUTO,
                sparse: SparseValues::Rgb9e5,
            },
        ),
        ("bc6h", CodecKind::Bc6h),
        ("f16", CodecKind::F16),
        ("f32", CodecKind::F32),
    ]
}

/// The f32 rounding bound of a sum of `n` non-negative products
/// (Higham, "Accuracy and Stability of Numerical Algorithms", §3.1:
/// `|ŝ − s| ≤ γ_n Σ|terms|`, `γ_n = n u / (1 − n u)`, and the terms are
/// non-negative so `Σ|terms| = s`), plus 4 u for the decode tables' and
/// the sparse values' own rounding; BC4's levels are looked up by their
/// numerator `k / (7 · 255)` where the reference divides two f32 values,
/// a relative difference of at most 2 u in `x`, amplified by `L x ≤ 30`
/// through `e^{L (x − 1)}`: 60 u more.
fn bound(n: usize, bc4: bool) -> f64 {
    let u = f32::EPSILON as f64 / 2.0;
    let g = n as f64 * u / (1.0 - n as f64 * u);
    g + 4.0 * u + if bc4 { 60.0 * u } else { 0.0 }
}

#[test]
fn gather_matches_the_reference_decode_for_every_codec() {
    for grey in [false, true] {
        let (t, b0, n) = problem(8, 2, grey);
        let b = refs(&b0);
        let exact = dense_product(refs(&t), n, b);
        for (name, kind) in kinds() {
            let e = encode::encode(kind, refs(&t), n).unwrap();
            let reference = e.gather_f64(b);
            let bc4 = matches!(e.format, radiosity::bakefile::codec::DenseFormat::Bc4);
            for simd in [false, true] {
                let g = CompressedGather::new(&e, simd);
                assert_eq!(g.simd(), simd && simd_available());
                let mut h: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
                let active = ActiveColumns::of(b, e.index.tile, false);
                let stats = g.gather(b, &active, &mut h);
                assert!(stats.bytes_read > 0);
                let tol = bound(n, bc4);
                let (mut d2, mut r2, mut worst) = (0.0f64, 0.0f64, 0.0f64);
                for c in 0..3 {
                    for i in 0..n {
                        let r = reference[c][i];
                        let rel = (h[c][i] as f64 - r).abs() / r.max(1e-30);
                        if r > 0.0 {
                            worst = worst.max(rel);
                        }
                        let x = exact[c][i];
                        d2 += (h[c][i] as f64 - x).powi(2);
                        r2 += x * x;
                    }
                }
                assert!(
                    worst <= tol,
                    "{name} (grey {grey}, simd {simd}): worst relative difference to the \
                     reference decode {worst:.3e} > {tol:.3e}"
                );
                // Against the exact product: the codec's own error, as the
                // f64 reference decode measures it, plus the rounding bound.
                let codec_error =
                    encode::h_error(&e, std::slice::from_ref(&exact), std::slice::from_ref(&b0));
                let err = (d2 / r2).sqrt();
                assert!(
                    err <= codec_error + tol,
                    "{name}: error {err:.4e} against the exact product exceeds the codec's \
                     {codec_error:.4e}"
                );
            }
        }
    }
}

#[test]
fn skipping_columns_changes_no_bit_and_reads_less() {
    let (t, mut b0, n) = problem(8, 2, false);
    // Half the patches' light (a product big enough for the thread pool),
    // then two patches' (small enough to run on the calling thread, while
    // every column still goes to the pool): the same bits either way.
    for lit in [usize::MAX, 2] {
        let mut seen = 0;
        for j in 0..n {
            if b0[0][j] != 0.0 {
                seen += 1;
                if seen > lit {
                    for c in &mut b0 {
                        c[j] = 0.0;
                    }
                }
            }
        }
        skipping_changes_no_bit(&t, &b0, n);
    }
}

fn skipping_changes_no_bit(t: &[Vec<f32>; 3], b0: &[Vec<f32>; 3], n: usize) {
    let b = refs(b0);
    for (name, kind) in kinds() {
        let e: Encoded = encode::encode(kind, refs(t), n).unwrap();
        for simd in [false, true] {
            let g = CompressedGather::new(&e, simd);
            let all = ActiveColumns::of(b, e.index.tile, true);
            let some = ActiveColumns::of(b, e.index.tile, false);
            assert!(
                some.active_groups < all.active_groups,
                "the light skips columns"
            );
            let mut h1: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
            let mut h2 = h1.clone();
            let s1 = g.gather(b, &all, &mut h1);
            let s2 = g.gather(b, &some, &mut h2);
            for c in 0..3 {
                for i in 0..n {
                    assert_eq!(
                        h1[c][i].to_bits(),
                        h2[c][i].to_bits(),
                        "{name} simd {simd}: H[{c}][{i}]"
                    );
                }
            }
            assert!(
                s2.bytes_read < s1.bytes_read,
                "{name}: {} bytes with skipping, {} without",
                s2.bytes_read,
                s1.bytes_read
            );
            // The sparse entries read: all, then exactly those of active
            // column groups (groups of 4 columns with some column lit).
            let lit = |g: usize| (4 * g..(4 * g + 4).min(n)).any(|j| b.iter().any(|c| c[j] != 0.0));
            let sp = &e.sparse.cols;
            assert_eq!(s1.sparse_entries, sp.len() as u64, "{name}");
            let expected = sp.iter().filter(|&&j| lit(j as usize / 4)).count() as u64;
            assert_eq!(s2.sparse_entries, expected, "{name} simd {simd}");
        }
    }
}

#[test]
fn a_zero_b0_gives_zero_and_reads_no_dense_data() {
    let (t, _, n) = problem(6, 0, false);
    let z: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
    let e = encode::encode(CodecKind::default(), refs(&t), n).unwrap();
    let g = CompressedGather::new(&e, true);
    let active = ActiveColumns::of(refs(&z), e.index.tile, false);
    assert_eq!(active.active_groups, 0);
    let mut h: [Vec<f32>; 3] = std::array::from_fn(|_| vec![1.0; n]);
    let s = g.gather(refs(&z), &active, &mut h);
    assert!(h.iter().all(|c| c.iter().all(|&v| v == 0.0)));
    assert_eq!(s.tiles_touched, 0);
    assert_eq!(s.entries, 0);
}

/// The vectorised path works through each row of tiles in segments of
/// active block columns (128 on AVX2) and decodes a full row of tiles'
/// keys eight blocks at a time, a shorter last row of tiles one block at a
/// time: a matrix wider than several segments, whose size is not a
/// multiple of the tile, with every column active, must give what the
/// portable path gives within the rounding bound (the two differ only in
/// fused multiply-adds), and skipping columns must still change no bit.
#[test]
fn the_vectorised_gather_matches_the_portable_one_across_segments_and_a_short_last_row() {
    let (t, b0, n) = problem(13, 3, false);
    let e = encode::encode(CodecKind::default(), refs(&t), n).unwrap();
    let tile = e.index.tile;
    assert!(n > 4 * 128 * 2, "{n} columns: more than two segments");
    assert!(
        n % tile != 0 && n % tile < tile - 4,
        "{n} patches: a short last row of tiles"
    );
    // Every column lit, with different values per channel.
    let full: [Vec<f32>; 3] = std::array::from_fn(|c| {
        (0..n)
            .map(|j| 0.1 + ((j * 7 + 3 * c) % 11) as f32)
            .collect()
    });
    let portable = CompressedGather::new(&e, false);
    // The CPU's widest kernels, and the AVX2 ones too on an AVX-512 host.
    for simd in [
        CompressedGather::new(&e, true),
        CompressedGather::new(&e, true).on_avx2(),
    ] {
        assert!(
            simd.simd(),
            "this CPU runs no vectorised path: the test cannot check it"
        );
        let kind = simd.vector_kind();
        for b in [refs(&full), refs(&b0)] {
            let all = ActiveColumns::of(b, tile, true);
            let some = ActiveColumns::of(b, tile, false);
            let mut hp: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
            let mut hs = hp.clone();
            let mut hk = hp.clone();
            portable.gather(b, &all, &mut hp);
            simd.gather(b, &all, &mut hs);
            simd.gather(b, &some, &mut hk);
            let tol = bound(n, false);
            for c in 0..3 {
                for i in 0..n {
                    let rel =
                        (hs[c][i] as f64 - hp[c][i] as f64).abs() / (hp[c][i] as f64).max(1e-30);
                    assert!(
                        rel <= tol,
                        "H[{c}][{i}]: {} vectorised ({kind}), {} portable",
                        hs[c][i],
                        hp[c][i]
                    );
                    assert_eq!(
                        hs[c][i].to_bits(),
                        hk[c][i].to_bits(),
                        "skipping changed H[{c}][{i}] ({kind})"
                    );
                }
            }
        }
    }
}

/// Matrices smaller than a block and than a tile (n = 1 to 9, 33 and 70),
/// for every codec: the vectorised path decodes a short last row of tiles
/// alone, with a partial last block column whose missing columns read `B0`
/// as zero; f16 and f32 images are `n` wide, so their last blocks are
/// partial too (padded at load). Both paths must agree with the reference
/// decode within the rounding bound.
#[test]
fn tiny_matrices_gather_alike_on_both_paths() {
    let mut rng = synthetic::Rng::new(11);
    for (n, (kname, kind)) in (1..=9)
        .chain([33, 70])
        .flat_map(|n| kinds().into_iter().map(move |k| (n, k)))
    {
        // A positive matrix spread over four decades, as transfer rows are.
        let t: [Vec<f32>; 3] = std::array::from_fn(|_| {
            (0..n * n)
                .map(|_| (10f64.powf(-4.0 * rng.uniform()) * 0.1) as f32)
                .collect()
        });
        let b0: [Vec<f32>; 3] =
            std::array::from_fn(|_| (0..n).map(|_| rng.uniform() as f32).collect());
        let e = encode::encode(kind, refs(&t), n).unwrap();
        let b = refs(&b0);
        let all = ActiveColumns::of(b, e.index.tile, true);
        let mut hp: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
        let mut hs = hp.clone();
        CompressedGather::new(&e, false).gather(b, &all, &mut hp);
        CompressedGather::new(&e, true).gather(b, &all, &mut hs);
        let reference = e.gather_f64(b);
        let tol = bound(n, e.format == DenseFormat::Bc4);
        for c in 0..3 {
            for i in 0..n {
                let r = reference[c][i];
                for (name, h) in [("portable", &hp), ("vectorised", &hs)] {
                    let rel = (h[c][i] as f64 - r).abs() / r.max(1e-30);
                    assert!(
                        rel <= tol,
                        "n = {n}, {kname}, {name}: H[{c}][{i}] = {} against {r}",
                        h[c][i]
                    );
                }
            }
        }
    }
}

/// `e` (BC1, tiles of 32) re-laid with tiles of 64, an edge the reader
/// accepts (up to `MAX_TILE`) though the encoder writes 32: each new tile
/// holds its four old tiles' blocks, all-zero blocks (which decode to 0)
/// where an old tile was not stored, and is stored when any of them was.
fn retiled_64(e: &Encoded) -> Encoded {
    assert_eq!(e.format, DenseFormat::Bc1);
    let (old, new) = (e.index.tile, 64);
    assert_eq!(old, 32);
    let image = e.image_size;
    let tps = image.div_ceil(new);
    let slot = |tr: usize, tc: usize| {
        (e.index.row_start[tr] as usize..e.index.row_start[tr + 1] as usize)
            .find(|&s| e.index.cols[s] as usize == tc)
    };
    let mut out = e.clone();
    out.dense.clear();
    out.index = TileIndex {
        tile: new,
        tiles_per_side: tps,
        row_start: vec![0],
        cols: Vec::new(),
        offsets: Vec::new(),
    };
    for tr in 0..tps {
        for tc in 0..tps {
            let subs: Vec<Vec<Option<usize>>> = (0..2)
                .map(|a| {
                    (0..2)
                        .map(|b| {
                            let (r, c) = (2 * tr + a, 2 * tc + b);
                            (r < e.index.tiles_per_side && c < e.index.tiles_per_side)
                                .then(|| slot(r, c))
                                .flatten()
                        })
                        .collect()
                })
                .collect();
            if subs.iter().flatten().all(Option::is_none) {
                continue;
            }
            out.index.cols.push(tc as u16);
            out.index.offsets.push(out.dense.len() as u32);
            let (h, w) = (new.min(image - tr * new), new.min(image - tc * new));
            for br in 0..h / 4 {
                for bc in 0..w / 4 {
                    let (a, b) = (br / 8, bc / 8);
                    match subs[a][b] {
                        None => out.dense.extend_from_slice(&[0; 8]),
                        Some(s) => {
                            let old_w = old.min(image - (2 * tc + b) * old);
                            let k = (br % 8) * (old_w / 4) + bc % 8;
                            let at = e.index.offsets[s] as usize + 8 * k;
                            out.dense.extend_from_slice(&e.dense[at..at + 8]);
                        }
                    }
                }
            }
        }
        out.index.row_start.push(out.index.cols.len() as u32);
    }
    out
}

/// A bake file may hold tiles larger than the encoder's 32 (the reader
/// accepts edges up to 256): the gather must then give the same `H` as
/// with the encoder's tiles, on every path and with skipping, rather than
/// run a vector kernel sized for 32-row tiles on them. A block-sparse
/// matrix (zero tiles) so that the re-laid tiles mix stored and missing
/// parts; n not a multiple of 64, so that the last row of tiles is short.
#[test]
fn tiles_larger_than_the_encoders_gather_the_same() {
    let (mut t, b0, n) = problem(13, 3, false);
    // Zero the coupling between the first and second half (block-sparse).
    let half = n / 2;
    for c in &mut t {
        for i in 0..n {
            for j in 0..n {
                if (i < half) != (j < half) {
                    c[i * n + j] = 0.0;
                }
            }
        }
    }
    assert!(n % 64 != 0, "{n}: a short last row of 64-tiles");
    let e = encode::encode(CodecKind::default(), refs(&t), n).unwrap();
    let tps = e.index.tiles_per_side;
    assert!(
        e.index.cols.len() < tps * tps,
        "no zero tile: the test needs some"
    );
    let big = retiled_64(&e);
    assert!(big.index.cols.len() < big.index.tiles_per_side.pow(2));
    let reference = CompressedGather::new(&e, false);
    let b = refs(&b0);
    let mut want: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
    reference.gather(b, &ActiveColumns::of(b, 32, true), &mut want);
    for simd in [false, true] {
        let g = CompressedGather::new(&big, simd);
        let (mut got, mut skipped) = (want.clone(), want.clone());
        g.gather(b, &ActiveColumns::of(b, 64, true), &mut got);
        g.gather(b, &ActiveColumns::of(b, 64, false), &mut skipped);
        let tol = bound(n, false);
        for c in 0..3 {
            for i in 0..n {
                let rel =
                    (got[c][i] as f64 - want[c][i] as f64).abs() / (want[c][i] as f64).max(1e-30);
                assert!(
                    rel <= tol,
                    "simd {simd}: H[{c}][{i}] {} with tiles of 64, {} of 32",
                    got[c][i],
                    want[c][i]
                );
                assert_eq!(got[c][i].to_bits(), skipped[c][i].to_bits());
            }
        }
    }
}

/// Column scales (`Encoded::col_scale`, what the bake stores: each column
/// divided by its patch's relative area): the stored matrix is
/// `T' = T diag(1/s)` and every decoder multiplies `s ∘ B0`. Scales over
/// six decades, every codec: the reference decode gives exactly what the
/// unscaled encoding of `T'` gives for `s ∘ B0`; `decode` gives `T'`'s
/// columns times `s`; the run-time gather (both paths, with skipping)
/// agrees with the reference within its rounding bound (one more rounding:
/// `s ∘ B0` in f32, below the bound's slack of 4 u); and against the exact
/// `T · B0` the error is the codec's own on `T'`.
#[test]
fn column_scales_are_applied_by_every_decoder() {
    let (t, b0, n) = problem(8, 2, false);
    let s: Vec<f32> = (0..n)
        .map(|j| 10f32.powf(-6.0 * ((j * 37) % n) as f32 / n as f32))
        .collect();
    let tp: [Vec<f32>; 3] =
        std::array::from_fn(|c| (0..n * n).map(|k| t[c][k] / s[k % n]).collect());
    let b = refs(&b0);
    let sb: [Vec<f32>; 3] =
        std::array::from_fn(|c| b0[c].iter().zip(&s).map(|(x, y)| x * y).collect());
    let exact = dense_product(refs(&t), n, b);
    for (name, kind) in kinds() {
        let plain = encode::encode(kind, refs(&tp), n).unwrap();
        let mut e = plain.clone();
        e.col_scale = s.clone();
        let reference = e.gather_f64(b);
        assert_eq!(reference, plain.gather_f64(refs(&sb)), "{name}");
        let (d, dp) = (e.decode(), plain.decode());
        for c in 0..3 {
            for k in 0..n * n {
                assert_eq!(d[c][k], dp[c][k] * s[k % n], "{name}: decode");
            }
        }
        let bc4 = matches!(e.format, DenseFormat::Bc4);
        for simd in [false, true] {
            let g = CompressedGather::new(&e, simd);
            for all in [true, false] {
                let mut h: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
                g.gather(b, &ActiveColumns::of(b, e.index.tile, all), &mut h);
                for c in 0..3 {
                    for i in 0..n {
                        let r = reference[c][i];
                        let rel = (h[c][i] as f64 - r).abs() / r.max(1e-30);
                        assert!(
                            rel <= bound(n, bc4),
                            "{name} simd {simd}: H[{c}][{i}] {} vs {r}",
                            h[c][i]
                        );
                    }
                }
            }
        }
        let err = encode::h_error(&e, std::slice::from_ref(&exact), std::slice::from_ref(&b0));
        let err_plain = encode::h_error(
            &plain,
            &[dense_product(refs(&tp), n, refs(&sb))],
            std::slice::from_ref(&sb),
        );
        assert!(
            (err - err_plain).abs() <= 1e-6 + 1e-3 * err_plain,
            "{name}: {err} with scales, {err_plain} for T' alone"
        );
    }
}

/// A grey matrix (one stored channel) gathering coloured light, each BC4
/// block decoded once for the three channels of `B0` (on the vector path by
/// a permute instead of a lookup per lane), and grey light, one product. The vector and portable paths
/// give the same bits (the same values, products and order), and both stay
/// within the rounding bound of the reference decode.
#[test]
fn a_grey_matrix_gathers_coloured_light_alike_on_both_paths() {
    // Coloured light (three products), then grey light (one).
    for scales in [[1.0f32, 0.5, 0.25], [1.0; 3]] {
        grey_matrix_alike_on_both_paths(scales);
    }
}

fn grey_matrix_alike_on_both_paths(scales: [f32; 3]) {
    let (t, b0, n) = problem(8, 2, true);
    // The first channel's light, scaled per channel.
    let b0: [Vec<f32>; 3] = std::array::from_fn(|c| b0[0].iter().map(|v| v * scales[c]).collect());
    let b = refs(&b0);
    for (name, kind) in kinds() {
        let e = encode::encode(kind, refs(&t), n).unwrap();
        // BC6H is an RGB format: it stores three equal channels.
        if matches!(kind, CodecKind::Bc6h) {
            assert_eq!(e.channels, 3);
            continue;
        }
        assert_eq!(
            e.channels, 1,
            "{name}: the grey matrix is stored in one channel"
        );
        let reference = e.gather_f64(b);
        let bc4 = matches!(e.format, DenseFormat::Bc4);
        let active = ActiveColumns::of(b, e.index.tile, false);
        let h: Vec<[Vec<f32>; 3]> = [false, true]
            .iter()
            .map(|&simd| {
                let mut h: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
                CompressedGather::new(&e, simd).gather(b, &active, &mut h);
                h
            })
            .collect();
        for c in 0..3 {
            for i in 0..n {
                assert_eq!(
                    h[0][c][i].to_bits(),
                    h[1][c][i].to_bits(),
                    "{name}: H[{c}][{i}] portable {} vs vector {}",
                    h[0][c][i],
                    h[1][c][i]
                );
                let r = reference[c][i];
                let rel = (h[1][c][i] as f64 - r).abs() / r.max(1e-30);
                assert!(
                    rel <= bound(n, bc4),
                    "{name}: H[{c}][{i}] {} vs {r}",
                    h[1][c][i]
                );
            }
        }
        // The channels differ as B0's do (or not, for grey light).
        let differ = h[1][1].iter().zip(&h[1][0]).any(|(a, b)| a != b);
        assert_eq!(differ, scales[1] != scales[0], "{name}");
    }
}

/// `T̃`'s column sums of magnitudes, read tile by tile, are those of the
/// decoded matrix for every codec, with column scales too: the same f32
/// values summed in f64 (each sum within `n · ε₆₄` of exact), the scale
/// applied once per column in f64 where the decode rounds it into each
/// entry in f32 (at most `u` apart per entry).
#[test]
fn column_sums_are_those_of_the_decoded_matrix_for_every_codec() {
    let (t, _, n) = problem(8, 2, false);
    let s: Vec<f32> = (0..n)
        .map(|j| 10f32.powf(-3.0 * ((j * 37) % n) as f32 / n as f32))
        .collect();
    let u = f32::EPSILON as f64 / 2.0;
    let tol = u + 2.0 * n as f64 * f64::EPSILON;
    for (name, kind) in kinds() {
        let plain = encode::encode(kind, refs(&t), n).unwrap();
        let mut scaled = plain.clone();
        scaled.col_scale = s.clone();
        for e in [plain, scaled] {
            let sums = e.column_sums();
            let d = e.decode();
            for c in 0..3 {
                for j in 0..n {
                    let expected: f64 = (0..n).map(|i| (d[c][i * n + j] as f64).abs()).sum();
                    assert!(
                        (sums[c][j] - expected).abs() <= tol * expected,
                        "{name} scaled {}: column {j} channel {c}: {} vs {expected}",
                        !e.col_scale.is_empty(),
                        sums[c][j]
                    );
                }
            }
        }
    }
}

/// Culling negligible columns ([`ActiveColumns::culled`]): it keeps a
/// subset of the lit groups, fewer as `eps` grows, dropping the lightest
/// first; the dropped groups' bound is at most `eps` of the total; the
/// product it gives differs from the exact one by at most that bound in
/// L1 (plus both products' f32 rounding, `γ_n` of the total each, and
/// the decode tables' `4 u`: [`bound`]); and at `eps = 0` it is the exact
/// skipping, bit for bit. Light spanning six decades, so that some columns
/// are negligible, on every codec and both paths.
#[test]
fn culling_drops_the_lightest_columns_within_its_bound() {
    let (t, mut b0, n) = problem(8, 2, false);
    for c in &mut b0 {
        for (j, v) in c.iter_mut().enumerate() {
            *v *= 10f32.powf(-6.0 * ((j * 53) % n) as f32 / n as f32);
        }
    }
    let b = refs(&b0);
    for (name, kind) in kinds() {
        let e = encode::encode(kind, refs(&t), n).unwrap();
        let weights = e.column_sums();
        let tile = e.index.tile;
        let exact = ActiveColumns::of(b, tile, false);
        let bc4 = matches!(e.format, DenseFormat::Bc4);
        let group_mass = |g: usize| -> f64 {
            (4 * g..(4 * g + 4).min(n))
                .map(|j| {
                    (0..3)
                        .map(|c| weights[c][j] * (b[c][j] as f64).abs())
                        .sum::<f64>()
                })
                .sum()
        };
        let kept =
            |a: &ActiveColumns, g: usize| a.mask[g / (tile / 4)] >> (g % (tile / 4)) & 1 == 1;
        for simd in [false, true] {
            let g = CompressedGather::new(&e, simd);
            let mut h_exact: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
            g.gather(b, &exact, &mut h_exact);
            let mut last = usize::MAX;
            for eps in [0.0, 1e-4, 1e-3, 1e-2, 0.1] {
                let cu = ActiveColumns::culled(b, tile, &weights, eps);
                let a = &cu.columns;
                assert!(a.active_groups <= last, "{name}: fewer groups as eps grows");
                last = a.active_groups;
                assert_eq!(
                    a.active_groups + cu.culled_groups,
                    exact.active_groups,
                    "{name}"
                );
                assert!(cu.dropped_mass <= eps * cu.mass, "{name} eps {eps}");
                let (mut dropped_max, mut kept_min) = (0.0f64, f64::INFINITY);
                for grp in 0..n.div_ceil(4) {
                    assert!(
                        !kept(a, grp) || kept(&exact, grp),
                        "{name}: only lit groups kept"
                    );
                    if kept(&exact, grp) {
                        if kept(a, grp) {
                            kept_min = kept_min.min(group_mass(grp));
                        } else {
                            dropped_max = dropped_max.max(group_mass(grp));
                        }
                    }
                }
                assert!(
                    dropped_max <= kept_min,
                    "{name} eps {eps}: the lightest go first"
                );
                let mut h: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
                g.gather(b, a, &mut h);
                if eps == 0.0 {
                    assert_eq!(a, &exact, "{name}: every column of T̃ is non-zero here");
                    assert_eq!(h, h_exact, "{name} simd {simd}: eps 0 is exact");
                    continue;
                }
                let diff: f64 = (0..3)
                    .flat_map(|c| (0..n).map(move |i| (c, i)))
                    .map(|(c, i)| (h[c][i] as f64 - h_exact[c][i] as f64).abs())
                    .sum();
                let slack = 2.0 * bound(n, bc4) * cu.mass;
                assert!(
                    diff <= cu.dropped_mass + slack,
                    "{name} simd {simd} eps {eps}: L1 difference {diff} > bound {} + {slack}",
                    cu.dropped_mass
                );
            }
            assert!(
                last < exact.active_groups,
                "{name}: eps 0.1 drops some groups"
            );
        }
        // An input that overflowed culls nothing: every lit group stays.
        let mut inf = b0.clone();
        let j = inf[0].iter().position(|&v| v != 0.0).unwrap();
        inf[0][j] = f32::INFINITY;
        let cu = ActiveColumns::culled(refs(&inf), tile, &weights, 0.1);
        assert_eq!(
            cu.columns,
            ActiveColumns::of(refs(&inf), tile, false),
            "{name}"
        );
    }
}
