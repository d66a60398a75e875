//! Tests of the compressed transfer matrix (crates/bakefile/src/codec/mod.rs): every codec's
//! round trip against stated bounds, the run-time gather against
//! decode-then-multiply, zero handling, tiles, sizes, determinism, the
//! choice under an error bound, the report, and the serialization into
//! the bake file's codec sections (round trip and rejection of corrupt
//! sections).

use radiosity::bake::encode;
use radiosity::bake::reorder::{self, ReorderMethod};
use radiosity::bakefile::codec::{self, CodecKind, DenseFormat, Encoded, SparseValues};
use radiosity::core::compute::Backend;
use radiosity::core::patch::Patch;
use radiosity::synthetic;

fn refs(t: &[Vec<f32>; 3]) -> [&[f32]; 3] {
    [&t[0][..], &t[1][..], &t[2][..]]
}

/// The synthetic room's `T_∞` (n = 6 m² + 6 b²) in the Hilbert order (the
/// codec sees reordered matrices), with its patches.
fn room(m: usize, b: usize) -> (Vec<Patch>, [Vec<f32>; 3]) {
    let patches = synthetic::room(m, b);
    let n = patches.len();
    let f = synthetic::form_factors(&patches);
    let t = synthetic::transfer_rgb(&patches, &f);
    let p = reorder::hilbert_order(&patches);
    let patches: Vec<Patch> = p
        .order
        .iter()
        .map(|&i| patches[i as usize].clone())
        .collect();
    let t = std::array::from_fn(|c| p.apply_symmetric(&t[c], n));
    (patches, t)
}

/// The coloured one-bounce matrix `t_c(i, j) = F_ij ρ_c(j)`: exact zeros
/// (coplanar patches) shared by the three channels.
fn coloured_f(patches: &[Patch]) -> [Vec<f32>; 3] {
    let n = patches.len();
    let f = synthetic::form_factors(patches);
    std::array::from_fn(|c| {
        (0..n * n)
            .map(|k| f[k] * patches[k % n].albedo[c] as f32)
            .collect()
    })
}

fn bc1(top: f64, l: f32, sparse: SparseValues) -> CodecKind {
    CodecKind::Bc1Log {
        top_fraction: top,
        log_range: l,
        sparse,
    }
}

fn bc4(top: f64, l: f32) -> CodecKind {
    CodecKind::Bc4Log {
        top_fraction: top,
        log_range: l,
        sparse: SparseValues::F32,
    }
}

/// Whether entry (i, j) is in the sparse part.
fn sparse_positions(e: &Encoded) -> std::collections::HashSet<(usize, usize)> {
    let mut s = std::collections::HashSet::new();
    for (i, w) in e.sparse.row_ptr.windows(2).enumerate() {
        for p in w[0] as usize..w[1] as usize {
            s.insert((i, e.sparse.cols[p] as usize));
        }
    }
    s
}

#[test]
fn f32_is_exact_and_costs_twelve_bytes() {
    let (_, t) = room(6, 2);
    let n = t[0].len().isqrt();
    let e = encode::encode(CodecKind::F32, refs(&t), n).unwrap();
    let d = e.decode();
    assert_eq!(d, t);
    assert_eq!(e.bytes_dense(), 12 * n * n);
    assert_eq!(e.bytes_sparse(), 0);
    assert_eq!(
        e.bytes_total(),
        e.bytes_dense() + e.bytes_sparse() + e.bytes_index()
    );
    assert!((e.bytes_per_entry() - e.bytes_total() as f64 / (n * n) as f64).abs() < 1e-12);
    let m = encode::measure(refs(&t), n, &d, &[]);
    assert_eq!(m.total_abs, 0.0);
    assert_eq!(m.rel_frobenius, 0.0);
}

#[test]
fn f16_is_within_half_an_ulp() {
    let (_, t) = room(6, 2);
    let n = t[0].len().isqrt();
    let e = encode::encode(CodecKind::F16, refs(&t), n).unwrap();
    assert_eq!(e.bytes_dense(), 6 * n * n);
    let d = e.decode();
    for c in 0..3 {
        // Values times a power of two lie in the normal half range (the
        // scale puts the maximum in [2^14, 2^15)), where rounding errs by at
        // most 2^-11 relative.
        let max = t[c].iter().cloned().fold(0.0f32, f32::max);
        for (&x, &y) in t[c].iter().zip(&d[c]) {
            if x >= max * 2f32.powi(-29) {
                assert!((y - x).abs() <= 2f32.powi(-11) * x, "{x} -> {y}");
            } else {
                assert!((y - x).abs() <= max * 2f32.powi(-40), "{x} -> {y}");
            }
        }
    }
}

/// Per-entry relative errors of a log codec, `|ln(T̃/(κ T))|` over the
/// nonzero dense entries that decode nonzero: (rms, max), with the mass
/// correction κ (a per-channel constant factor) taken out. Also checks that
/// the sparse entries are exact.
fn log_errors(e: &Encoded, t: &[Vec<f32>; 3], d: &[Vec<f32>; 3]) -> (f64, f64) {
    let n = e.n;
    let sparse = sparse_positions(e);
    let (mut sum2, mut max, mut count) = (0.0f64, 0.0f64, 0usize);
    for c in 0..3 {
        let k = e.stats.mass_correction[if e.channels == 1 { 0 } else { c }];
        for i in 0..n {
            for j in 0..n {
                let (x, y) = (t[c][i * n + j] as f64, d[c][i * n + j] as f64);
                if sparse.contains(&(i, j)) {
                    assert_eq!(x, y, "sparse entry ({i}, {j}) is not exact");
                    continue;
                }
                if x > 0.0 && y > 0.0 {
                    let r = (y / (k * x)).ln().abs();
                    sum2 += r * r;
                    max = max.max(r);
                    count += 1;
                }
            }
        }
    }
    ((sum2 / count as f64).sqrt(), max)
}

#[test]
fn bc1_log_error_bounds() {
    let (_, t) = room(8, 2);
    let n = t[0].len().isqrt();
    for (kind, rms_bound, max_bound) in [
        // Errors in ln-space (≈ relative). The log rounding alone errs by
        // at most L/510 (0.05 at L = 25, 0.008 at the automatic L ≈ 3.9 of
        // this matrix). BC1 adds its 5:6:5 endpoint grid (a 5-bit step is
        // 8.2 byte levels, L/31 in ln-space; interpolation splits it in
        // thirds) and the 4-colour fit of each block's 16 texels, which is
        // what dominates: measured rms 0.12 and max 1.05 at the automatic
        // L, rms 0.15 / max 1.6 at L = 25 (the max sits in blocks mixing
        // the largest dense entries with much smaller ones). The bounds
        // leave ~1.4× margin.
        (
            bc1(0.04, codec::LOG_RANGE_AUTO, SparseValues::F32),
            0.17,
            1.5,
        ),
        (CodecKind::THESIS, 0.21, 2.3),
    ] {
        let e = encode::encode(kind, refs(&t), n).unwrap();
        assert_eq!(e.format, DenseFormat::Bc1);
        let d = e.decode();
        let (rms, max) = log_errors(&e, &t, &d);
        eprintln!(
            "{kind}: L = {}, rms {rms:.3}, max {max:.3}, κ {:?}",
            e.log_range, e.stats.mass_correction
        );
        assert!(rms <= rms_bound, "{kind}: rms {rms}");
        assert!(max <= max_bound, "{kind}: max {max}");
        // The correction removes BC1's bias: measured within 3 % of 1.
        for k in e.stats.mass_correction {
            assert!((k - 1.0).abs() < 0.05, "mass correction {k}");
        }
        // The sparse part holds the top 4 % of positions (exactly).
        assert_eq!(e.sparse.len(), (0.04 * (n * n) as f64).round() as usize);
        assert_eq!(e.stats.zeros_lost, 0);
        // 0.5 bytes per entry of BC1, 14 per sparse position (u16 column,
        // three f32), u32 row pointers.
        assert_eq!(e.bytes_dense(), n.div_ceil(4).pow(2) * 8);
        assert_eq!(e.bytes_sparse(), (n + 1) * 4 + e.sparse.len() * 14);
    }
}

#[test]
fn bc4_and_bc6h_error_bounds() {
    let (_, t) = room(8, 2);
    let n = t[0].len().isqrt();
    // BC4: 8-bit endpoints and 8 levels per block, decoded at float
    // precision: measured rms 0.056 and max 0.34 in ln-space.
    let e = encode::encode(bc4(0.04, codec::LOG_RANGE_AUTO), refs(&t), n).unwrap();
    assert_eq!(e.format, DenseFormat::Bc4);
    assert_eq!(e.bytes_dense(), 3 * n.div_ceil(4).pow(2) * 8);
    let d = e.decode();
    let (rms, max) = log_errors(&e, &t, &d);
    eprintln!("bc4: L = {}, rms {rms:.3}, max {max:.3}", e.log_range);
    assert!(rms <= 0.1 && max <= 0.6, "bc4: rms {rms}, max {max}");
    // BC6H: half-float endpoints interpolated on their bit patterns (about
    // 4 bits per texel between them), no sparse part: measured relative
    // Frobenius error 0.107 on this matrix, dominated by the large
    // near-diagonal entries, which share blocks with much smaller ones.
    let e = encode::encode(CodecKind::Bc6h, refs(&t), n).unwrap();
    assert_eq!(e.bytes_dense(), n.div_ceil(4).pow(2) * 16);
    let m = encode::measure(refs(&t), n, &e.decode(), &[]);
    eprintln!("bc6h: {m}");
    assert!(m.rel_frobenius < 0.15, "{m}");
}

#[test]
fn gather_equals_decode_then_multiply() {
    let (patches, t) = room(6, 2);
    let n = patches.len();
    let lights = synthetic::point_lights(&patches, 2, 1);
    let grey = [&t[1][..], &t[1][..], &t[1][..]];
    let mut cases: Vec<(CodecKind, [&[f32]; 3])> = [
        bc1(0.04, codec::LOG_RANGE_AUTO, SparseValues::F16),
        bc1(0.0, 25.0, SparseValues::F32),
        bc4(0.02, 12.0),
        CodecKind::Bc6h,
        CodecKind::F16,
        CodecKind::F32,
    ]
    .into_iter()
    .map(|k| (k, refs(&t)))
    .collect();
    cases.push((CodecKind::default(), grey));
    cases.push((CodecKind::F32, grey));
    for (kind, tm) in cases {
        let e = encode::encode(kind, tm, n).unwrap();
        let d = e.decode();
        for b0 in &lights {
            let g = e.gather(refs(b0));
            for c in 0..3 {
                let h = encode::mat_vec(&d[c], n, &b0[c]);
                for i in 0..n {
                    // f32 accumulation of n dense and the sparse terms:
                    // within (n + 2) 2^-24 Σ_j |T̃_ij b_j| of the f64 sum.
                    let abs: f64 = (0..n)
                        .map(|j| (d[c][i * n + j] * b0[c][j]).abs() as f64)
                        .sum();
                    let tol = (n + 2) as f64 * 2f64.powi(-24) * abs;
                    assert!(
                        (g[c][i] as f64 - h[i]).abs() <= tol,
                        "{kind} channel {c} row {i}: {} vs {}",
                        g[c][i],
                        h[i]
                    );
                }
            }
        }
    }
}

#[test]
fn zero_tiles_are_skipped_and_counted() {
    // Two rooms that do not see each other: T is block diagonal, with
    // sizes (n1 = 6·25, n2 = 6·36) that are multiples of neither 4 nor the
    // tile. The off-diagonal blocks are exactly zero.
    let (_, t1) = room(5, 0);
    let (_, t2) = room(6, 0);
    let (n1, n2) = (t1[0].len().isqrt(), t2[0].len().isqrt());
    let n = n1 + n2;
    let t: [Vec<f32>; 3] = std::array::from_fn(|c| {
        let mut m = vec![0.0f32; n * n];
        for i in 0..n1 {
            m[i * n..i * n + n1].copy_from_slice(&t1[c][i * n1..(i + 1) * n1]);
        }
        for i in 0..n2 {
            m[(n1 + i) * n + n1..(n1 + i + 1) * n].copy_from_slice(&t2[c][i * n2..(i + 1) * n2]);
        }
        m
    });
    for kind in [
        CodecKind::F32,
        CodecKind::F16,
        bc1(0.02, codec::LOG_RANGE_AUTO, SparseValues::F16),
        bc4(0.0, 12.0),
        CodecKind::Bc6h,
    ] {
        let e = encode::encode(kind, refs(&t), n).unwrap();
        // A tile is empty iff its part of the (padded) matrix is all zero.
        let tile = codec::TILE;
        let tps = e.image_size.div_ceil(tile);
        let mut empty = 0;
        for tr in 0..tps {
            for tc in 0..tps {
                let rows = tr * tile..((tr + 1) * tile).min(n);
                let nonzero = rows.clone().any(|i| {
                    (tc * tile..((tc + 1) * tile).min(n))
                        .any(|j| (0..3).any(|c| t[c][i * n + j] != 0.0))
                });
                empty += usize::from(!nonzero);
            }
        }
        assert_eq!(e.stats.tiles_total, tps * tps);
        assert_eq!(e.stats.tiles_total - e.stats.tiles_stored, empty, "{kind}");
        assert!(
            e.stats.tiles_skipped_fraction > 0.3,
            "{kind}: {}",
            e.stats.tiles_skipped_fraction
        );
        assert_eq!(e.index.cols.len(), e.stats.tiles_stored);
        // Zeros in the stored tiles straddling the two blocks stay zero
        // (BC6H: only where its encoder keeps them; counted).
        let d = e.decode();
        let lost: usize = (0..3)
            .map(|c| {
                (0..n1)
                    .map(|i| {
                        d[c][i * n + n1..(i + 1) * n]
                            .iter()
                            .filter(|&&v| v != 0.0)
                            .count()
                    })
                    .sum::<usize>()
            })
            .sum();
        if kind == CodecKind::Bc6h {
            assert!(lost as u64 <= e.stats.zeros_lost);
        } else {
            assert_eq!(lost, 0, "{kind}");
        }
        eprintln!(
            "{kind}: {:.1} % of tiles skipped, {:.3} B/entry",
            100.0 * e.stats.tiles_skipped_fraction,
            e.bytes_per_entry()
        );
    }
}

#[test]
fn exact_zeros_stay_zero() {
    let patches = synthetic::room(6, 2);
    let n = patches.len();
    let t = coloured_f(&patches);
    let zeros = t[0].iter().filter(|&&v| v == 0.0).count();
    assert!(zeros > n * n / 10, "the test needs zeros: {zeros}");
    for kind in [
        bc1(0.04, codec::LOG_RANGE_AUTO, SparseValues::F16),
        bc1(0.0, 25.0, SparseValues::F32),
        bc4(0.02, codec::LOG_RANGE_AUTO),
        CodecKind::F16,
        CodecKind::F32,
    ] {
        let e = encode::encode(kind, refs(&t), n).unwrap();
        let d = e.decode();
        for c in 0..3 {
            for (k, (&x, &y)) in t[c].iter().zip(&d[c]).enumerate() {
                if x == 0.0 {
                    assert_eq!(
                        y,
                        0.0,
                        "{kind}: zero ({}, {}) of channel {c} decodes to {y}",
                        k / n,
                        k % n
                    );
                }
            }
        }
        assert_eq!(e.stats.zeros_lost, 0, "{kind}");
        if matches!(kind, CodecKind::Bc1Log { .. } | CodecKind::Bc4Log { .. }) {
            assert!(
                e.stats.mixed_zero_blocks > 0,
                "{kind}: the zero-keeping mode was not exercised"
            );
        }
    }
    // BC6H keeps zeros only where the encoder does: its count is reported
    // and agrees with the measurement.
    let e = encode::encode(CodecKind::Bc6h, refs(&t), n).unwrap();
    let m = encode::measure(refs(&t), n, &e.decode(), &[]);
    assert_eq!(m.zeros_changed, e.stats.zeros_lost);
    eprintln!(
        "bc6h: {} of {} zeros decode nonzero",
        e.stats.zeros_lost,
        3 * zeros
    );

    // A texel zero in one channel only (G) cannot be forced to zero by
    // BC1's black: whatever happens is counted.
    let mut partial = t.clone();
    for k in (0..n * n).step_by(7) {
        partial[1][k] = 0.0;
    }
    let e = encode::encode(bc1(0.0, 12.0, SparseValues::F32), refs(&partial), n).unwrap();
    let m = encode::measure(refs(&partial), n, &e.decode(), &[]);
    assert_eq!(m.zeros_changed, e.stats.zeros_lost);
}

/// Entries of `−0` (which a transfer matrix's round-off can make, and the
/// encoder accepts) are zeros like `+0` to the log formats: the same bytes,
/// the same sparse part. (The sparse ranking once read a `−0`'s bit
/// pattern as the largest key and stored those entries first.)
#[test]
fn negative_zeros_encode_as_zeros() {
    let patches = synthetic::room(6, 2);
    let n = patches.len();
    let t = coloured_f(&patches);
    // Every third exact zero made −0 in every channel, every fifth in the
    // green one only.
    let mut neg = t.clone();
    let mut changed = 0;
    for k in 0..n * n {
        if t[0][k] == 0.0 && t[1][k] == 0.0 && t[2][k] == 0.0 {
            if k % 3 == 0 {
                for ch in neg.iter_mut() {
                    ch[k] = -0.0;
                }
                changed += 1;
            } else if k % 5 == 0 {
                neg[1][k] = -0.0;
                changed += 1;
            }
        }
    }
    assert!(changed > n, "the test needs zeros: {changed}");
    for kind in [
        bc1(0.04, codec::LOG_RANGE_AUTO, SparseValues::Rgb9e5),
        bc1(0.02, 12.0, SparseValues::F16),
        bc4(0.02, codec::LOG_RANGE_AUTO),
    ] {
        let a = encode::encode(kind, refs(&neg), n).unwrap();
        let b = encode::encode(kind, refs(&t), n).unwrap();
        assert_same_encoding(&a, &b, &format!("{kind}, −0 against +0"));
    }
}

#[test]
fn grey_input_is_stored_once() {
    let (patches, t) = room(6, 2);
    let n = patches.len();
    let g = [&t[1][..], &t[1][..], &t[1][..]];
    let lights = synthetic::point_lights(&patches, 1, 5);
    // BC1 on a grey matrix stores one BC4 channel: the same 0.5 bytes per
    // entry, with 8-bit endpoints. Plain formats store one channel.
    let e = encode::encode(CodecKind::default(), g, n).unwrap();
    assert!(e.stats.grey);
    assert_eq!((e.format, e.channels), (DenseFormat::Bc4, 1));
    assert_eq!(e.bytes_dense(), n.div_ceil(4).pow(2) * 8);
    let col = encode::encode(CodecKind::default(), refs(&t), n).unwrap();
    // One value per sparse position instead of three: a u16 column and one
    // f16 value (the default's precision).
    assert_eq!(e.bytes_sparse(), (n + 1) * 4 + e.sparse.len() * 4);
    assert!(col.bytes_sparse() > e.bytes_sparse());
    let d = e.decode();
    assert!(d[0] == d[1] && d[1] == d[2]);
    let grey_err = encode::measure(g, n, &d, &lights);
    let colour_err = encode::measure(refs(&t), n, &col.decode(), &lights);
    eprintln!("grey (bc4): {grey_err}\ncolour (bc1): {colour_err}");
    assert!(grey_err.rel_frobenius < colour_err.rel_frobenius);
    let f = encode::encode(CodecKind::F32, g, n).unwrap();
    assert_eq!(f.bytes_dense(), 4 * n * n);
    assert_eq!(f.decode()[2], t[1]);
    // Identical content in distinct slices is detected as grey too.
    let copy = t[1].clone();
    let e2 = encode::encode(CodecKind::F32, [&t[1][..], &copy[..], &t[1][..]], n).unwrap();
    assert!(e2.stats.grey);
}

#[test]
fn sizes_that_are_not_multiples_of_four_or_the_tile() {
    for n in [1usize, 3, 5, 37, 101] {
        let mut rng = synthetic::Rng(n as u64);
        let t: [Vec<f32>; 3] = std::array::from_fn(|_| {
            (0..n * n)
                .map(|_| {
                    let u = rng.uniform();
                    if u < 0.2 {
                        0.0
                    } else {
                        (u * 1e-2) as f32
                    }
                })
                .collect()
        });
        let f = encode::encode(CodecKind::F32, refs(&t), n).unwrap();
        assert_eq!(f.decode(), t);
        assert_eq!(f.image_size, n);
        let b0: [Vec<f32>; 3] = std::array::from_fn(|c| (0..n).map(|i| (i + c) as f32).collect());
        for kind in [
            bc1(0.04, codec::LOG_RANGE_AUTO, SparseValues::F32),
            CodecKind::Bc6h,
            bc4(0.1, 8.0),
        ] {
            let e = encode::encode(kind, refs(&t), n).unwrap();
            assert_eq!(e.image_size, n.div_ceil(4) * 4);
            let d = e.decode();
            assert!(d.iter().all(|c| c.len() == n * n));
            let g = e.gather(refs(&b0));
            for c in 0..3 {
                let h = encode::mat_vec(&d[c], n, &b0[c]);
                for i in 0..n {
                    assert!(
                        (g[c][i] as f64 - h[i]).abs() <= 1e-5 * h[i].abs().max(1e-30),
                        "n = {n}, {kind}"
                    );
                }
            }
        }
    }
}

#[test]
fn encoding_is_deterministic() {
    let (_, t) = room(6, 2);
    let n = t[0].len().isqrt();
    for kind in [
        bc1(0.04, codec::LOG_RANGE_AUTO, SparseValues::F16),
        bc4(0.02, 12.0),
        CodecKind::Bc6h,
    ] {
        let a = encode::encode(kind, refs(&t), n).unwrap();
        let b = encode::encode(kind, refs(&t), n).unwrap();
        assert_eq!(a.dense, b.dense, "{kind}");
        assert_eq!(a.sparse, b.sparse, "{kind}");
        assert_eq!(a.index, b.index, "{kind}");
        assert_eq!(a.scale, b.scale, "{kind}");
        assert_eq!(a.log_range, b.log_range, "{kind}");
    }
}

#[test]
fn top_fraction_takes_the_largest_positions() {
    let (_, t) = room(6, 2);
    let n = t[0].len().isqrt();
    let e = encode::encode(bc1(0.05, 12.0, SparseValues::F32), refs(&t), n).unwrap();
    assert_eq!(e.sparse.len(), (0.05 * (n * n) as f64).round() as usize);
    let max: Vec<f32> = t
        .iter()
        .map(|c| c.iter().cloned().fold(0.0, f32::max))
        .collect();
    let key = |k: usize| (0..3).map(|c| t[c][k] * (1.0 / max[c])).sum::<f32>();
    let sparse = sparse_positions(&e);
    let (mut lo_in, mut hi_out) = (f32::INFINITY, 0.0f32);
    for k in 0..n * n {
        if sparse.contains(&(k / n, k % n)) {
            lo_in = lo_in.min(key(k));
        } else {
            hi_out = hi_out.max(key(k));
        }
    }
    assert!(lo_in >= hi_out, "{lo_in} < {hi_out}");
    assert!(e.stats.sparse_mass_fraction > 0.05);
}

#[test]
fn choose_picks_the_cheapest_within_the_bound() {
    let (patches, t) = room(6, 2);
    let n = patches.len();
    let lights = synthetic::point_lights(&patches, 3, 2);
    let candidates = [
        CodecKind::F32,
        CodecKind::F16,
        bc1(0.04, codec::LOG_RANGE_AUTO, SparseValues::F16),
        bc1(0.0, 25.0, SparseValues::F32),
    ];
    let reference: Vec<[Vec<f64>; 3]> = lights
        .iter()
        .map(|b| std::array::from_fn(|c| encode::mat_vec(&t[c], n, &b[c])))
        .collect();
    let errs: Vec<(f64, usize)> = candidates
        .iter()
        .map(|&k| {
            let e = encode::encode(k, refs(&t), n).unwrap();
            let err = encode::h_error(&e, &reference, &lights);
            // The f64 gather agrees with decode-then-multiply.
            let m = encode::measure(refs(&t), n, &e.decode(), &lights).rel_rms_h;
            assert!((err - m).abs() <= 1e-9 * m.max(1e-300), "{k}: {err} vs {m}");
            (err, e.bytes_total())
        })
        .collect();
    eprintln!("{errs:?}");
    for bound in [0.0, 1e-3, 0.02, 1.0] {
        let (kind, e, err) = encode::choose(refs(&t), n, &lights, bound, &candidates).unwrap();
        assert!(err <= bound);
        let cheapest = errs
            .iter()
            .zip(&candidates)
            .filter(|(e, _)| e.0 <= bound)
            .min_by_key(|(e, _)| e.1)
            .unwrap();
        assert_eq!(kind, *cheapest.1, "bound {bound}");
        assert_eq!(e.bytes_total(), cheapest.0 .1);
    }
    assert_eq!(
        encode::choose(refs(&t), n, &lights, 0.0, &candidates)
            .unwrap()
            .0,
        CodecKind::F32
    );
    let err = encode::choose(refs(&t), n, &lights, 1e-9, &candidates[3..]).unwrap_err();
    assert!(err.to_string().contains("no codec"), "{err}");
    assert!(encode::choose(refs(&t), n, &[], 0.1, &candidates).is_err());
}

#[test]
fn check_accepts_encodings_and_catches_corruption() {
    let (patches, t) = room(5, 1);
    let n = patches.len();
    let b0 = synthetic::point_lights(&patches, 1, 4).remove(0);
    for kind in [
        CodecKind::default(),
        CodecKind::Bc6h,
        CodecKind::F16,
        CodecKind::F32,
    ] {
        let e = encode::encode(kind, refs(&t), n).unwrap();
        e.check().unwrap();
        // The error measure's one-pass gather over many B0 is the f64
        // gather of each, bit for bit: 40 of them, a block of 32 samples
        // summed in registers (`core::products`) and 8 one at a time.
        let bs: Vec<[Vec<f32>; 3]> = (0..40)
            .map(|s| {
                std::array::from_fn(|c| {
                    b0[c]
                        .iter()
                        .map(|&v| v / (1 + s) as f32 + 0.125 * (c + s % 3) as f32)
                        .collect()
                })
            })
            .collect();
        let many = e.gather_many_f64(&bs.iter().map(refs).collect::<Vec<_>>());
        for (s, b) in bs.iter().enumerate() {
            assert_eq!(many[s], e.gather_f64(refs(b)), "{kind}: B0 {s}");
        }
        let mut bad = e.clone();
        bad.dense.truncate(bad.dense.len() - 1);
        assert!(bad.check().is_err(), "{kind}: truncated dense part");
        let mut bad = e.clone();
        bad.index.cols[0] = u16::MAX;
        assert!(bad.check().is_err(), "{kind}: tile column out of range");
        let mut bad = e.clone();
        bad.n += 1;
        assert!(bad.check().is_err(), "{kind}: size");
        if !e.sparse.is_empty() {
            let mut bad = e.clone();
            bad.sparse.cols[3] = n as u32;
            assert!(bad.check().is_err(), "{kind}: sparse column out of range");
        }
    }
    // For F32 the f64 gather is the f64 product, term for term.
    let e = encode::encode(CodecKind::F32, refs(&t), n).unwrap();
    let g = e.gather_f64(refs(&b0));
    for c in 0..3 {
        assert_eq!(g[c], encode::mat_vec(&t[c], n, &b0[c]));
    }
}

#[test]
fn names_parse_back_and_bad_input_is_an_error() {
    for k in encode::default_candidates() {
        assert_eq!(CodecKind::parse(&k.name()).unwrap(), k, "{k}");
    }
    assert_eq!(CodecKind::parse("bc1").unwrap(), CodecKind::default());
    assert_eq!(
        CodecKind::parse("bc1:top=0.02,L=12,sparse=f16").unwrap(),
        bc1(0.02, 12.0, SparseValues::F16)
    );
    for bad in ["bc2", "bc1:top=2", "bc1:L=-1", "f32:top=0.1", "bc1:x=1"] {
        assert!(CodecKind::parse(bad).is_err(), "{bad}");
    }
    let mut t = [0.5f32; 16];
    t[5] = -1.0;
    let err = encode::encode(CodecKind::F32, [&t[..], &t[..], &t[..]], 4).unwrap_err();
    assert!(err.to_string().contains("(1, 1)"), "{err}");
    t[5] = f32::NAN;
    assert!(encode::encode(CodecKind::F16, [&t[..], &t[..], &t[..]], 4).is_err());
    assert!(encode::encode(CodecKind::F16, [&t[..], &t[..], &t[..]], 5).is_err());
    // An all-zero matrix stores nothing dense.
    let z = vec![0.0f32; 64 * 64];
    let e = encode::encode(CodecKind::default(), [&z[..], &z[..], &z[..]], 64).unwrap();
    assert_eq!((e.bytes_dense(), e.bytes_sparse()), (0, 0));
    assert_eq!(e.decode()[0], z);
}

#[test]
fn report_lists_every_method_and_codec() {
    let (patches, t) = room(5, 0);
    let n = patches.len();
    let lights = synthetic::point_lights(&patches, 2, 9);
    let methods = [
        ReorderMethod::None,
        ReorderMethod::SpaceFillingCurve,
        ReorderMethod::Greedy { passes: 2 },
    ];
    let kinds = [CodecKind::default(), CodecKind::F32];
    let rows = radiosity::bench::compression::report_rows(
        refs(&t),
        n,
        &patches,
        &lights,
        &methods,
        &kinds,
        Backend::Cpu,
    )
    .unwrap();
    assert_eq!(rows.len(), 6);
    assert!(rows
        .iter()
        .filter(|r| r.codec == "f32")
        .all(|r| r.error.rel_rms_h == 0.0));
    let table = radiosity::bench::compression::report_table(&rows);
    assert_eq!(table.lines().count(), 2 + 6);
    assert!(table.contains("greedy:2") && table.contains("hilbert"));
    serde_json::to_string(&rows).unwrap();
}

/// Field-by-field equality of two encodings (statistics aside, which are
/// informative and hold times).
fn assert_same_encoding(a: &Encoded, b: &Encoded, what: &str) {
    assert_eq!(a.kind, b.kind, "{what}: kind");
    assert_eq!(a.n, b.n, "{what}: n");
    assert_eq!(a.channels, b.channels, "{what}: channels");
    assert_eq!(a.format, b.format, "{what}: format");
    assert_eq!(a.image_size, b.image_size, "{what}: image size");
    assert_eq!(
        a.scale.map(f32::to_bits),
        b.scale.map(f32::to_bits),
        "{what}: scale"
    );
    assert_eq!(a.log_range.to_bits(), b.log_range.to_bits(), "{what}: L");
    assert_eq!(a.index, b.index, "{what}: tile index");
    assert!(a.dense == b.dense, "{what}: dense bytes");
    assert_eq!(a.sparse.row_ptr, b.sparse.row_ptr, "{what}: sparse rows");
    assert_eq!(a.sparse.cols, b.sparse.cols, "{what}: sparse columns");
    // Bit equality: f16 sparse values must survive value × scale → half →
    // value exactly (the scale is a power of two).
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(
        bits(&a.sparse.values),
        bits(&b.sparse.values),
        "{what}: sparse values"
    );
}

/// Every variant, grey and coloured, with and without a sparse part, at a
/// size that is not a multiple of 4 or of the tile: `to_blob` then
/// `from_blob` (also through a whole bake file's bytes) gives back the same
/// encoding, so the run time gathers the same `H` bit for bit.
#[test]
fn blobs_round_trip_every_variant() {
    let (patches, t) = room(7, 1); // n = 6·49 + 6 = 300
    let n = patches.len();
    let grey: [Vec<f32>; 3] = std::array::from_fn(|_| t[1].clone());
    let b0 = synthetic::point_lights(&patches, 1, 9).remove(0);
    let kinds = [
        CodecKind::THESIS,
        CodecKind::default(),
        bc1(0.04, codec::LOG_RANGE_AUTO, SparseValues::Rgb9e5),
        bc1(0.02, codec::LOG_RANGE_AUTO, SparseValues::F16),
        bc1(0.0, codec::LOG_RANGE_AUTO, SparseValues::F16),
        bc4(0.02, 12.0),
        CodecKind::Bc6h,
        CodecKind::F16,
        CodecKind::F32,
    ];
    for (matrix, label) in [(&t, "colour"), (&grey, "grey")] {
        for kind in kinds {
            let what = format!("{kind} ({label})");
            let e = encode::encode(kind, refs(matrix), n).unwrap();
            let blob = e.to_blob();
            let back = Encoded::from_blob(&blob).unwrap();
            assert_same_encoding(&e, &back, &what);
            assert_eq!(back.gather(refs(&b0)), e.gather(refs(&b0)), "{what}: H");
            // The sections' sizes are what bytes_per_entry counts (the
            // sparse section adds its 24-byte header, the index section
            // its 20-byte header and the 16 header bytes counted there are
            // the scales and L).
            assert_eq!(blob.dense.len(), e.bytes_dense(), "{what}");
            assert_eq!(
                blob.sparse.len(),
                codec::blob::layout::SPARSE_HEADER + e.bytes_sparse(),
                "{what}"
            );
            // Through the container.
            let records: Vec<radiosity::bakefile::PatchRecord> = patches
                .iter()
                .map(radiosity::bakefile::PatchRecord::from)
                .collect();
            let centres: Vec<([f32; 3], [f32; 3])> =
                records.iter().map(|p| (p.centre, p.normal)).collect();
            let bf = radiosity::bakefile::BakeFile {
                options_json: "{}".into(),
                info_json: "{}".into(),
                surface_map: radiosity::bakefile::surface::SurfaceMap::without_geometry(n),
                samples: radiosity::bakefile::surface::PatchSamples::at_centres(&centres),
                patches: records,
                permutation: (0..n as u32).collect(),
                codec: blob,
                ..Default::default()
            };
            let bytes = radiosity::bakefile::encode(&bf).unwrap();
            let read = radiosity::bakefile::parse(&bytes).unwrap();
            assert_same_encoding(&e, &Encoded::from_blob(&read.codec).unwrap(), &what);
        }
    }
}

/// Corrupt codec sections (with valid checksums: what a hostile or buggy
/// writer produces) are errors naming the section, never a panic: one test
/// per field, then every single-byte change and truncation of the index
/// and sparse sections.
#[test]
fn corrupt_codec_sections_are_rejected() {
    let (_, t) = room(5, 1);
    let n = t[0].len().isqrt();
    let e = encode::encode(
        bc1(0.04, codec::LOG_RANGE_AUTO, SparseValues::F16),
        refs(&t),
        n,
    )
    .unwrap();
    let good = e.to_blob();
    let expect_err = |b: &radiosity::bakefile::CodecBlob, needle: &str, what: &str| {
        let err = Encoded::from_blob(b).expect_err(what).to_string();
        assert!(
            err.contains(needle),
            "{what}: {err:?} should mention {needle:?}"
        );
    };
    let mut b = good.clone();
    b.kind = 77;
    expect_err(&b, "CDSC", "unknown format code");
    let mut b = good.clone();
    b.kind = DenseFormat::Bc6h.code();
    expect_err(&b, "TIDX", "format not matching the codec");
    let mut b = good.clone();
    b.params_json = r#"{"codec":"jpeg"}"#.into();
    expect_err(&b, "CPRM", "unknown codec name");
    let mut b = good.clone();
    b.params_json = "[1, 2]".into();
    expect_err(&b, "CPRM", "parameters not an object");
    let mut b = good.clone();
    b.tile_index.truncate(b.tile_index.len() - 2);
    expect_err(&b, "TIDX", "truncated tile index");
    let mut b = good.clone();
    b.tile_index.extend_from_slice(&[0, 0]);
    expect_err(&b, "trailing", "trailing bytes in the tile index");
    let mut b = good.clone();
    b.sparse.truncate(b.sparse.len() - 1);
    expect_err(&b, "SPRS", "truncated sparse part");
    let mut b = good.clone();
    b.sparse[0] = 9; // precision
    expect_err(&b, "SPRS", "unknown sparse precision");
    let mut b = good.clone();
    let last = b.sparse.len() - 2;
    b.sparse[last..].copy_from_slice(&half::f16::NAN.to_bits().to_le_bytes());
    expect_err(&b, "not finite", "NaN sparse value");
    let mut b = good.clone();
    b.dense.truncate(b.dense.len() - 8);
    expect_err(&b, "invalid encoded matrix", "truncated dense part");
    let mut b = good.clone();
    b.n += 1;
    assert!(Encoded::from_blob(&b).is_err(), "wrong n");
    // A tile edge that is consistent with one tile per side but huge (found
    // by the fuzzer: the gather's tile buffer overflowed).
    let small = encode::encode(CodecKind::F32, refs(&t), n).unwrap();
    let mut b = small.to_blob();
    b.tile_size = 1 << 30;
    let tps = u32::from_le_bytes(b.tile_index[8..12].try_into().unwrap());
    if tps == 1 {
        expect_err(&b, "tile edge", "huge tile edge");
    }
    let mut b = small.to_blob();
    b.tile_size = 4096;
    expect_err(&b, "tile edge", "tile edge above the bound");
    // Plain formats: a NaN among the dense values.
    let f = encode::encode(CodecKind::F32, refs(&t), n).unwrap();
    let mut b = f.to_blob();
    b.dense[4..8].copy_from_slice(&f32::NAN.to_le_bytes());
    expect_err(&b, "DENS", "NaN in f32 dense data");

    // Every byte of the index and sparse sections changed: an error, or an
    // encoding that passes `check` (a changed value or offset can be valid)
    // and gathers finite values without panicking. Every truncation is an
    // error: each section's length is fully determined by its header.
    let b0 = [vec![1.0f32; n], vec![0.5; n], vec![0.25; n]];
    fn section(b: &mut radiosity::bakefile::CodecBlob, s: usize) -> &mut Vec<u8> {
        if s == 0 {
            &mut b.tile_index
        } else {
            &mut b.sparse
        }
    }
    for s in 0..2 {
        let len = section(&mut good.clone(), s).len();
        for k in 0..len {
            let mut b = good.clone();
            section(&mut b, s).truncate(k);
            assert!(Encoded::from_blob(&b).is_err(), "section {s} cut at {k}");
            for delta in [0x01u8, 0x80] {
                let mut b = good.clone();
                section(&mut b, s)[k] ^= delta;
                if let Ok(e) = Encoded::from_blob(&b) {
                    let h = e.gather(refs(&b0));
                    assert!(h.iter().flatten().all(|x| x.is_finite()));
                }
            }
        }
    }
}

/// GL_RGB9_E5 as EXT_texture_shared_exponent specifies it: exact for
/// values on the format's grid, every channel within 2^-9 of the triple's
/// largest value otherwise (the largest channel's mantissa is at least 256
/// after rounding, so half a step is at most max / 512) as long as that
/// value is above 2^-16, clamped above.
#[test]
fn rgb9e5_follows_the_specification() {
    use codec::rgb9e5::{pack, unpack, MAX};
    assert_eq!(pack([1.0, 1.0, 1.0]), 256 | 256 << 9 | 256 << 18 | 16 << 27);
    assert_eq!(unpack(pack([1.0, 0.5, 0.25])), [1.0, 0.5, 0.25]);
    assert_eq!(unpack(pack([0.0; 3])), [0.0; 3]);
    assert_eq!(unpack(pack([MAX, 0.0, 1.0]))[0], MAX);
    assert_eq!(unpack(pack([1e9, -1.0, f32::NAN])), [MAX, 0.0, 0.0]);
    // 511.5 · 2^-8 rounds up to a mantissa of 512: the exponent moves up.
    assert_eq!(unpack(pack([511.5 / 256.0, 0.0, 0.0]))[0], 2.0);
    let mut rng = synthetic::Rng(7);
    for _ in 0..100_000 {
        let scale = 2f64.powf(30.0 * rng.uniform() - 15.0);
        let v: [f32; 3] = std::array::from_fn(|_| (rng.uniform().powi(3) * scale) as f32);
        let max = v.iter().cloned().fold(0.0f32, f32::max) as f64;
        let back = unpack(pack(v));
        // Below 2^-16 the exponent is at its floor and the step stays 2^-24
        // (the format's denormal range): half a step, 2^-25, bounds the error.
        let bound = (max / 512.0).max(2f64.powi(-25)) * (1.0 + 1e-6);
        for c in 0..3 {
            let err = (back[c] as f64 - v[c] as f64).abs();
            assert!(err <= bound, "{v:?} -> {back:?}");
        }
    }
}

/// Sparse values in RGB9E5 cost 4 bytes a position instead of 6 (f16) or
/// 12 (f32), and `H` barely notices: their error (≤ 2^-9 of a position's
/// largest channel) is far below BC1's on the dense part. A grey matrix
/// stores f16 instead (one channel has no exponent to share).
#[test]
fn rgb9e5_sparse_values_are_cheaper_at_the_same_error() {
    let (patches, t) = room(8, 2);
    let n = patches.len();
    let lights = synthetic::point_lights(&patches, 8, 3);
    let f32s = encode::encode(
        bc1(0.04, codec::LOG_RANGE_AUTO, SparseValues::F32),
        refs(&t),
        n,
    )
    .unwrap();
    let e5 = encode::encode(
        bc1(0.04, codec::LOG_RANGE_AUTO, SparseValues::Rgb9e5),
        refs(&t),
        n,
    )
    .unwrap();
    assert_eq!(e5.sparse.precision, SparseValues::Rgb9e5);
    assert_eq!(e5.bytes_sparse(), (n + 1) * 4 + e5.sparse.len() * 6);
    assert_eq!(e5.sparse.cols, f32s.sparse.cols, "the same positions");
    for (p, (a, b)) in f32s
        .sparse
        .values
        .chunks_exact(3)
        .zip(e5.sparse.values.chunks_exact(3))
        .enumerate()
    {
        let max = a.iter().cloned().fold(0.0f32, f32::max) as f64;
        for c in 0..3 {
            let err = (a[c] as f64 - b[c] as f64).abs();
            assert!(
                err <= max / 512.0 * (1.0 + 1e-6),
                "position {p}: {a:?} vs {b:?}"
            );
        }
    }
    let err = |e: &Encoded| encode::measure(refs(&t), n, &e.decode(), &lights).rel_rms_h;
    let (ef, ee) = (err(&f32s), err(&e5));
    eprintln!("H error: f32 sparse {ef:.4e}, rgb9e5 sparse {ee:.4e}");
    assert!(ee <= ef * 1.05 + 1e-6, "rgb9e5 {ee} vs f32 {ef}");
    let grey = [&t[1][..], &t[1][..], &t[1][..]];
    let g = encode::encode(
        bc1(0.04, codec::LOG_RANGE_AUTO, SparseValues::Rgb9e5),
        grey,
        n,
    )
    .unwrap();
    assert_eq!((g.channels, g.sparse.precision), (1, SparseValues::F16));
    assert_eq!(
        CodecKind::parse("bc1:sparse=rgb9e5").unwrap(),
        bc1(0.04, codec::LOG_RANGE_AUTO, SparseValues::Rgb9e5)
    );
}

/// The codec choice's estimate (`encode::h_error_estimate`, every
/// `stride`-th row of tiles) against the full measure, over every default
/// candidate on the synthetic room (1,632 patches, 51 rows of tiles): the
/// estimate stays within its own margin (`Estimate::margin`, from its
/// standard error) of the full error, so no candidate within the bound is
/// rejected on it, and the choice with the estimate equals the choice
/// without it.
#[test]
fn the_choices_estimate_rejects_only_what_the_full_measure_would() {
    let (patches, t) = room(16, 4);
    let n = patches.len();
    let lights = synthetic::point_lights(&patches, 8, 5);
    let reference: Vec<[Vec<f64>; 3]> = lights
        .iter()
        .map(|b| std::array::from_fn(|c| encode::mat_vec(&t[c], n, &b[c])))
        .collect();
    // The bake's own stride: none up to 191 rows of tiles (6,112 patches,
    // where the estimate would not pay for itself), then 1 row of tiles in
    // ⌊tiles / 48⌋.
    assert_eq!(encode::estimate_stride(n), 1);
    assert_eq!(encode::estimate_stride(6_112), 1);
    assert_eq!(encode::estimate_stride(6_113), encode::ESTIMATE_MIN_STRIDE);
    assert_eq!(encode::estimate_stride(32_000), 1_000 / 48);
    let stride = 4;
    let mut worst = (1.0f64, 1.0f64);
    for kind in encode::default_candidates() {
        let e = encode::encode(kind, refs(&t), n).unwrap();
        let sampled = encode::encode_sampled(kind, refs(&t), n, stride).unwrap();
        let full = encode::h_error(&e, &reference, &lights);
        let estimate = encode::h_error_estimate(&sampled, &reference, &lights, stride);
        let est = estimate.error;
        assert_eq!(estimate.rows, n.div_ceil(codec::TILE).div_ceil(stride));
        // With stride 1 the estimate is the full measure, with no sampling
        // error; the full measure equals the decoded matrix's product
        // (`encode::measure`: decode, then f64 products per sample) up to
        // the order of its f64 sums (8 ε n, as faer bounds a sum of n
        // terms; measured: 1e-16).
        assert_eq!(
            encode::h_error_estimate(&e, &reference, &lights, 1).std_error,
            0.0
        );
        let decoded = encode::measure(refs(&t), n, &e.decode(), &lights).rel_rms_h;
        assert!(
            (decoded - full).abs() <= 8.0 * f64::EPSILON * n as f64,
            "{kind}: gathered {full:e}, decoded {decoded:e}"
        );
        // The sampled encoding stores the full one's tiles in its rows of
        // tiles, byte for byte, and nothing in the others; only the log
        // formats' mass correction (the scale) may differ.
        let tps = e.index.tiles_per_side;
        assert_eq!(sampled.index.tiles_per_side, tps);
        for tr in 0..tps {
            let (a, b) = (&e.index, &sampled.index);
            let full_row = &a.cols[a.row_start[tr] as usize..a.row_start[tr + 1] as usize];
            let kept = &b.cols[b.row_start[tr] as usize..b.row_start[tr + 1] as usize];
            if tr % stride == 0 {
                assert_eq!(full_row, kept, "{kind}: row of tiles {tr}");
            } else {
                assert!(kept.is_empty(), "{kind}: row of tiles {tr}");
            }
        }
        let row_bytes = |x: &radiosity_bakefile::codec::Encoded, tr: usize| {
            let (s, e) = (
                x.index.row_start[tr] as usize,
                x.index.row_start[tr + 1] as usize,
            );
            let start = x
                .index
                .offsets
                .get(s)
                .map_or(x.dense.len(), |&o| o as usize);
            let end = x
                .index
                .offsets
                .get(e)
                .map_or(x.dense.len(), |&o| o as usize);
            x.dense[start..end].to_vec()
        };
        for tr in (0..tps).step_by(stride) {
            assert_eq!(
                row_bytes(&e, tr),
                row_bytes(&sampled, tr),
                "{kind}: bytes of row {tr}"
            );
        }
        assert_eq!(sampled.sparse.cols, e.sparse.cols);
        if kind.log_params().is_none() {
            assert_eq!(sampled.scale, e.scale);
            assert_eq!(
                est.to_bits(),
                encode::h_error_estimate(&e, &reference, &lights, stride)
                    .error
                    .to_bits()
            );
        }
        if full > 0.0 {
            let r = est / full;
            let margin = estimate.margin();
            eprintln!(
                "{kind}: full {full:.4e}, estimate {est:.4e} ± {:.2e}, ratio {r:.3}, margin {margin:.3}",
                estimate.std_error
            );
            worst = (worst.0.min(r), worst.1.max(r));
            assert!(
                (encode::ESTIMATE_MIN_MARGIN..=encode::ESTIMATE_MARGIN).contains(&margin),
                "{kind}: margin {margin}"
            );
            // Were the bound the full error itself, the estimate would not
            // reject: no candidate within a bound is rejected on it.
            assert!(
                !estimate.rejects(full),
                "{kind}: estimate {r} × the full error, margin {margin}"
            );
        }
    }
    eprintln!("estimate / full: {:.3} to {:.3}", worst.0, worst.1);
    let mut rejected_on_estimate = 0;
    for bound in [0.005, 0.01, 0.02, 0.05] {
        let pick = |s: usize| {
            let mut estimated = 0;
            let (kind, e, err) =
                encode::choose_with(refs(&t), n, &lights, bound, &[], s, &mut |_, _, _, how| {
                    estimated += usize::from(!how.is_full());
                })
                .unwrap();
            (kind, e.bytes_total(), err.to_bits(), estimated)
        };
        let (with, without) = (pick(stride), pick(1));
        assert_eq!(with.0, without.0, "bound {bound}");
        assert_eq!((with.1, with.2), (without.1, without.2));
        assert_eq!(without.3, 0);
        rejected_on_estimate += with.3;
        eprintln!(
            "bound {bound}: {} ({} candidates rejected on the estimate)",
            with.0, with.3
        );
    }
    // The tight bounds reject most candidates on the estimate: the path that
    // saves the full measures is exercised, not only the one that falls
    // through to them.
    assert!(rejected_on_estimate > 0);
}

/// The codec choice's exact reference, all samples in one pass over each
/// channel (`encode::exact_products`), equals `encode::mat_vec` per sample
/// and channel value for value: the same products summed in the same
/// order (an exact zero may differ in sign only, which `==` ignores).
#[test]
fn exact_products_equal_one_product_per_sample() {
    let (patches, t) = room(6, 3);
    // 40 lights: a block of 32 samples summed in registers
    // (`core::products`) and 8 one at a time; the whole matrix and a
    // leading block of it.
    let lights = synthetic::point_lights(&patches, 40, 11);
    for m in [patches.len(), patches.len() - 5] {
        let sub: [Vec<f32>; 3] = std::array::from_fn(|c| {
            (0..m)
                .flat_map(|i| t[c][i * patches.len()..i * patches.len() + m].to_vec())
                .collect()
        });
        let sub_lights: Vec<[Vec<f32>; 3]> = lights
            .iter()
            .map(|b| std::array::from_fn(|c| b[c][..m].to_vec()))
            .collect();
        let all = encode::exact_products(refs(&sub), m, &sub_lights);
        assert_eq!(all.len(), lights.len());
        for (h, b) in all.iter().zip(&sub_lights) {
            for c in 0..3 {
                assert_eq!(
                    h[c],
                    encode::mat_vec(&sub[c], m, &b[c]),
                    "{m} rows, channel {c}"
                );
            }
        }
    }
    assert!(encode::exact_products(refs(&t), patches.len(), &[]).is_empty());
}
