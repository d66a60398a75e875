//! The whole bake (crates/bake/src/lib.rs): voxelize → form factors → transfer →
//! reorder → encode → mesh map → `.rad`, checked through what the run time
//! will read. The file must read back to the same matrix, permutation and
//! map; the same inputs must give the same bytes; with the exact codec the
//! permutation must undo exactly; `--max-error` must meet its bound as
//! measured independently; `T_decoded.npy` must be the decoded matrix in
//! the order of `patches.csv`.

mod common;

use radiosity::bake::encode;
use radiosity::bake::reorder::ReorderMethod;

use radiosity::bake::voxelize::Resolution;
use radiosity::bake::{self, BakeConfig, BakeOutput, CodecChoice, ComputeChoice};
use radiosity::bakefile;
use radiosity::bakefile::codec::{CodecKind, Encoded};
use radiosity::core::compute::DeviceSelection;
use radiosity::core::permutation::Permutation;
use std::path::PathBuf;
use std::sync::OnceLock;

/// The Cornell box at ~300 patches: small enough for a few seconds per
/// bake, large enough for several tiles and a real reordering.
fn config(tag: &str) -> (BakeConfig, PathBuf) {
    let dir = common::temp_dir(tag);
    let sel = DeviceSelection::from_flag_or_env(None).expect("RADIOSITY_CL_DEVICE is malformed");
    let mut c = BakeConfig::new(common::bundled("cornell_box"), Resolution::Patches(300));
    c.compute = ComputeChoice::OpenCl(sel);
    c.error_lights = 8;
    c.output = Some(dir.join("cornell.rad"));
    (c, dir)
}

fn run(c: &BakeConfig) -> BakeOutput {
    // Fails with the device error when there is no OpenCL device.
    common::gpu();
    bake::run(c, &mut |_| {}).expect("the bake runs")
}

/// One default bake shared by the tests that only read it, with its
/// export directory.
fn default_bake() -> &'static (BakeOutput, BakeConfig) {
    static B: OnceLock<(BakeOutput, BakeConfig)> = OnceLock::new();
    B.get_or_init(|| {
        let (mut c, dir) = config("bake-default");
        c.export = Some(dir.join("export"));
        (run(&c), c)
    })
}

fn assert_same_matrix(a: &Encoded, b: &Encoded) {
    assert_eq!(a.kind, b.kind);
    assert_eq!((a.n, a.channels, a.format), (b.n, b.channels, b.format));
    assert_eq!(a.index, b.index);
    assert!(a.dense == b.dense, "dense bytes differ");
    assert_eq!(a.sparse, b.sparse);
    assert_eq!(a.scale, b.scale);
    assert_eq!(a.log_range, b.log_range);
}

#[test]
fn the_file_reads_back_to_what_was_baked() {
    let (out, c) = default_bake();
    let path = c.output.as_ref().unwrap();
    let file = bakefile::read(path).unwrap();
    assert_eq!(&file, &out.file, "the file holds what the bake returned");
    let n = out.patches.len();
    assert_eq!(file.patches.len(), n);
    assert_eq!(file.permutation, out.permutation.order);
    let encoded = Encoded::from_blob(&file.codec).unwrap();
    assert_same_matrix(&encoded, &out.encoded);
    // The default reordering at this size is the thesis's greedy method.
    assert_eq!(
        out.report.reorder.method,
        ReorderMethod::default_for(n).name()
    );
    // Every vertex of the mesh has a row; indices address the patches.
    assert_eq!(file.mesh_map.len(), out.report.scene.vertices);
    assert!(file
        .mesh_map
        .iter()
        .flatten()
        .all(|&(p, w)| (p as usize) < n && w >= 0.0));

    // The run time's path: B0 in patch order, permuted into matrix order,
    // gathered from the file's matrix, permuted back. Its error against
    // the exact T·B0 is the error the bake reported for this light.
    let scene = radiosity::core::scene::load(&c.scene).unwrap();
    let b0 = bake::error_samples(&scene, &out.patches, 1).remove(0);
    let perm = Permutation::from_order(file.permutation.clone()).unwrap();
    let bp: [Vec<f32>; 3] = std::array::from_fn(|ch| perm.apply_vec(&b0[ch]));
    let h = encoded.gather_f64([&bp[0], &bp[1], &bp[2]]);
    let (mut d2, mut r2) = (0.0, 0.0);
    for ch in 0..3 {
        let exact = out
            .transfer
            .apply(ch, &b0[ch].iter().map(|&x| x as f64).collect::<Vec<_>>());
        let got = perm.unapply_vec(&h[ch]);
        for (a, b) in exact.iter().zip(&got) {
            d2 += (a - b) * (a - b);
            r2 += a * a;
        }
    }
    let rel = (d2 / r2).sqrt();
    assert!(r2 > 0.0, "the light reaches the patches");
    // The default codec's H error on this scene is a few per cent (the
    // bake measured it over 8 lights); one light may be worse, not 3×.
    let reported = out.report.codec.h_error.unwrap();
    assert!(
        rel < 3.0 * reported + 1e-6,
        "H error {rel} vs reported {reported}"
    );
}

#[test]
fn t_decoded_is_the_decoded_matrix_in_patch_order() {
    let (out, c) = default_bake();
    let dir = c.export.as_ref().unwrap();
    let n = out.patches.len();
    let (shape, t) = radiosity::core::npy::read_f32(&dir.join("T.npy")).unwrap();
    assert_eq!(shape, [3, n, n]);
    let (shape, td) = radiosity::core::npy::read_f32(&dir.join("T_decoded.npy")).unwrap();
    assert_eq!(shape, [3, n, n]);
    let decoded = out.encoded.decode();
    let inv = &out.permutation.inverse;
    for ch in 0..3 {
        for i in 0..n {
            for j in 0..n {
                let want = decoded[ch][inv[i] as usize * n + inv[j] as usize];
                assert_eq!(td[(ch * n + i) * n + j].to_bits(), want.to_bits());
            }
        }
    }
    // Exact zeros of T stay exactly zero (module doc of codec.rs: zeros
    // come from geometry, shared by the channels).
    let zeros = t.iter().filter(|&&x| x == 0.0).count();
    let kept = t
        .iter()
        .zip(&td)
        .filter(|&(&a, &b)| a == 0.0 && b == 0.0)
        .count();
    assert_eq!(zeros, kept, "every exact zero of T decodes to 0");
}

#[test]
fn the_same_bake_gives_the_same_bytes() {
    let (out, c) = default_bake();
    let first = std::fs::read(c.output.as_ref().unwrap()).unwrap();
    let (mut again, _) = config("bake-again");
    again.error_lights = c.error_lights;
    let out2 = run(&again);
    let second = std::fs::read(again.output.as_ref().unwrap()).unwrap();
    let (a, b) = (&out.file, &out2.file);
    assert_eq!(a.options_json, b.options_json);
    assert_eq!(a.scene_hash, b.scene_hash);
    assert!(a.patches == b.patches, "patches differ");
    assert!(a.permutation == b.permutation, "permutations differ");
    assert_eq!(a.codec.params_json, b.codec.params_json);
    assert!(a.codec == b.codec, "codec data differ");
    assert!(a.mesh_map == b.mesh_map, "mesh maps differ");
    assert_eq!(a.info_json, b.info_json);
    assert!(first == second, "two bakes of the same scene differ");
}

#[test]
fn with_the_exact_codec_the_permutation_undoes_exactly() {
    let (mut c, _) = config("bake-f32");
    c.codec = CodecChoice::Fixed(CodecKind::F32);
    c.reorder = Some(ReorderMethod::Greedy { passes: 2 });
    let out = run(&c);
    let n = out.patches.len();
    let file = bakefile::read(c.output.as_ref().unwrap()).unwrap();
    let e = Encoded::from_blob(&file.codec).unwrap();
    let perm = Permutation::from_order(file.permutation).unwrap();
    assert!(
        perm.order.iter().enumerate().any(|(i, &p)| p as usize != i),
        "the greedy order is not the identity"
    );
    let inverse = Permutation::from_order(perm.inverse.clone()).unwrap();
    let decoded = e.decode();
    for (ch, d) in decoded.iter().enumerate() {
        let back = inverse.apply_symmetric(d, n);
        assert!(
            back == out.transfer.channel(ch),
            "channel {ch} is not T exactly"
        );
    }
    // H: the same exact products (f32 × f32 is exact in f64), summed in
    // another order: rounding ≤ n · 2^-53 · Σ|terms| per entry.
    let b0: [Vec<f32>; 3] =
        std::array::from_fn(|ch| (0..n).map(|i| ((i * 7 + ch) % 11) as f32 * 0.1).collect());
    let bp: [Vec<f32>; 3] = std::array::from_fn(|ch| perm.apply_vec(&b0[ch]));
    let h = e.gather_f64([&bp[0], &bp[1], &bp[2]]);
    for ch in 0..3 {
        let exact = encode::mat_vec(out.transfer.channel(ch), n, &b0[ch]);
        let got = perm.unapply_vec(&h[ch]);
        for (a, b) in exact.iter().zip(&got) {
            assert!((a - b).abs() <= n as f64 * f64::EPSILON * a.abs().max(1e-300));
        }
    }
    assert_eq!(out.report.codec.h_error, Some(0.0));
}

fn refs(t: &[Vec<f32>]) -> [&[f32]; 3] {
    [&t[0][..], &t[1][..], &t[2][..]]
}

#[test]
fn max_error_picks_a_setting_within_the_bound() {
    let (mut c, _) = config("bake-max-error");
    c.codec = CodecChoice::MaxError(0.05);
    c.reorder = Some(ReorderMethod::SpaceFillingCurve);
    let out = run(&c);
    let err = out.report.codec.h_error.unwrap();
    assert!(err <= 0.05, "{err}");
    assert!(out.report.codec.chosen_by.starts_with("max-error"));
    // The cheapest: nothing cheaper among the candidates meets the bound.
    let perm = &out.permutation;
    let scene = radiosity::core::scene::load(&c.scene).unwrap();
    let n = out.patches.len();
    let samples: Vec<[Vec<f32>; 3]> = bake::error_samples(&scene, &out.patches, c.error_lights)
        .iter()
        .map(|b| std::array::from_fn(|ch| perm.apply_vec(&b[ch])))
        .collect();
    // The bake tries the plain matrix, then T' = T diag(1/s) with s the
    // patches' relative areas (its error measure multiplying s ∘ B0), and
    // keeps the cheaper within the bound (at equal bytes, the smaller
    // error; the scales' own 4 n bytes not counted).
    let area: Vec<f64> = perm.apply_vec(&out.patches.iter().map(|p| p.area).collect::<Vec<_>>());
    let s = bake::column_scales(&area);
    let plain: Vec<Vec<f32>> = (0..3)
        .map(|ch| perm.apply_symmetric(out.transfer.channel(ch), n))
        .collect();
    let t_scaled: Vec<Vec<f32>> = plain
        .iter()
        .map(|t| t.iter().enumerate().map(|(k, v)| v / s[k % n]).collect())
        .collect();
    let s_samples: Vec<[Vec<f32>; 3]> = samples
        .iter()
        .map(|b| std::array::from_fn(|ch| b[ch].iter().zip(&s).map(|(x, y)| x * y).collect()))
        .collect();
    let exact = |t: &[Vec<f32>], b: &[[Vec<f32>; 3]]| -> Vec<[Vec<f64>; 3]> {
        b.iter()
            .map(|b| std::array::from_fn(|ch| encode::mat_vec(&t[ch], n, &b[ch])))
            .collect()
    };
    let (ref_plain, ref_scaled) = (exact(&plain, &samples), exact(&t_scaled, &s_samples));
    let scaled_chosen = !out.encoded.col_scale.is_empty();
    if scaled_chosen {
        assert_eq!(out.encoded.col_scale, s, "the stored column scales");
        assert!(out.report.codec.chosen_by.ends_with("columns scaled"));
    }
    // Measured again, independently of the bake: the same error (a scaled
    // matrix applies its scales to the unscaled samples).
    let reference = if scaled_chosen {
        &ref_scaled
    } else {
        &ref_plain
    };
    assert_eq!(encode::h_error(&out.encoded, reference, &samples), err);
    // The rule within each try (encode::choose): the cheapest passing
    // setting, unless a BC1/BC4 setting passes within BLOCK_CODEC_SLACK
    // times its bytes; then the cheapest such one. Checked on the plain
    // try against every candidate.
    let is_block = |k: CodecKind| matches!(k, CodecKind::Bc1Log { .. } | CodecKind::Bc4Log { .. });
    let (k0, e0, err0) =
        encode::choose(refs(&plain), n, &samples, 0.05, &[]).expect("a plain setting passes");
    let mut cheapest = usize::MAX;
    let mut cheapest_block = usize::MAX;
    for kind in encode::default_candidates() {
        let e = encode::encode(kind, refs(&plain), n).unwrap();
        if encode::h_error(&e, &ref_plain, &samples) <= 0.05 {
            cheapest = cheapest.min(e.bytes_total());
            if is_block(kind) {
                cheapest_block = cheapest_block.min(e.bytes_total());
            }
        }
    }
    if cheapest_block as f64 <= encode::BLOCK_CODEC_SLACK * cheapest as f64 {
        assert_eq!(
            e0.bytes_total(),
            cheapest_block,
            "the cheapest passing block setting"
        );
        assert!(is_block(k0));
    } else {
        assert_eq!(e0.bytes_total(), cheapest, "the cheapest passing setting");
    }
    // Then the scaled try over the log settings expected to cost no more,
    // and the cheaper of the two.
    let cheaper = encode::measure::log_candidates_no_dearer_than(k0);
    assert!(cheaper.iter().all(|k| k.log_params().is_some()
        && encode::measure::expected_bytes_per_entry(*k)
            <= encode::measure::expected_bytes_per_entry(k0)));
    let want = match encode::choose(refs(&t_scaled), n, &s_samples, 0.05, &cheaper) {
        Ok((_, e1, err1))
            if e1.bytes_total() < e0.bytes_total()
                || (e1.bytes_total() == e0.bytes_total() && err1 < err0) =>
        {
            (e1.bytes_total() + 4 * n, err1, true)
        }
        _ => (e0.bytes_total(), err0, false),
    };
    assert_eq!(
        (out.encoded.bytes_total(), err, scaled_chosen),
        want,
        "the bake's choice"
    );
}

#[test]
fn bad_codec_options_are_refused() {
    let (mut c, _) = config("bake-bad");
    c.codec = CodecChoice::MaxError(f64::NAN);
    // Typed errors naming the option (the binary adds the flag).
    let e = c.validate().unwrap_err();
    assert_eq!(e.option(), Some("maximum codec error"), "{e}");
    assert!(e.to_string().contains("NaN"), "{e}");
    c.codec = CodecChoice::MaxError(0.01);
    c.error_lights = 0;
    let e = c.validate().unwrap_err();
    assert_eq!(e.option(), Some("error lights"), "{e}");
    assert!(CodecKind::F32.with_top_fraction(0.1).is_err());
    assert!(CodecKind::default().with_top_fraction(1.5).is_err());
    assert_eq!(
        CodecKind::default().with_top_fraction(0.02).unwrap().name(),
        "bc1-log(top=0.02,L=auto,rgb9e5)"
    );
}
