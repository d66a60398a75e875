//! Bake step 6, the codec: the reordered matrix encoded with the fixed
//! setting or the cheapest setting within the error bound
//! (`BakeConfig::codec`), each also tried with its columns scaled by
//! patch area, the error of `H` measured against the exact product over
//! seeded random lights (docs/design.md section 3, measure 3).

use crate::config::{BakeConfig, CodecChoice, ERROR_LIGHTS_SEED};
use crate::encode;
use crate::error::BakeError;
use crate::report::{bar_at_most, spinner, CodecSummary};
use radiosity_bakefile::codec::Encoded;
use radiosity_core::direct;
use radiosity_core::patch::Patch;
use radiosity_core::permutation::Permutation;
use radiosity_core::scene;
use rayon::prelude::*;

/// What step 6 hands to the file: the encoded matrix, its summary (the
/// setting, how it was chosen, its measured `H` error), and how many
/// seeded lights measured it.
pub struct Encoding {
    pub encoded: Encoded,
    pub summary: CodecSummary,
    pub error_lights: u64,
}

/// Encodes the reordered matrix `permuted` (`n × n`, 1 or 3 channels; its
/// columns may be scaled in place when the scaled setting is tried) of the
/// `patches` (patch order) reordered by `perm`, as `config` asks.
pub fn encode(
    config: &BakeConfig,
    scene: &scene::Scene,
    patches: &[Patch],
    perm: &Permutation,
    permuted: &mut [Vec<f32>],
    n: usize,
    progress: &mut dyn FnMut(&str),
) -> Result<Encoding, BakeError> {
    let b0_samples: Vec<[Vec<f32>; 3]> = if config.error_lights > 0 {
        progress(&format!(
            "direct light from {} seeded random lights (for the compression error)",
            config.error_lights
        ));
        error_samples(scene, patches, config.error_lights)
            .iter()
            .map(|b| std::array::from_fn(|c| perm.apply_vec(&b[c])))
            .collect()
    } else {
        Vec::new()
    };
    // Column scales (`Encoded::col_scale`): each column divided by its
    // patch's area relative to the largest. They are a second setting
    // beside the codec's, tried where the error is measured and the codec
    // is a log one (a plain f32 or f16 matrix would only gain a rounding):
    // first the plain matrix, then, in place, `T' = T diag(1/s)` with the
    // samples `s ∘ B0`; the cheaper result within the bound is kept, at
    // equal bytes the smaller error (for a fixed codec, the smaller
    // error). On Sponza at 3,946 patches the scales halve BC1's error at a
    // given top fraction; at 12,872, and on the interior, they raise it
    // (docs/runtime.md).
    let scales =
        column_scales(&perm.apply_vec(&patches.iter().map(|p| p.area).collect::<Vec<f64>>()));
    let scaled_samples: Vec<[Vec<f32>; 3]> = b0_samples
        .iter()
        .map(|b| radiosity_bakefile::codec::scaled_input([&b[0], &b[1], &b[2]], &scales))
        .collect();
    // A fixed setting is one encoding: a spinner. The choice counts its
    // candidates against the most it may try in each pass (it stops at the
    // first within the bound and its block alternative), so its count and
    // time left are upper bounds.
    let sp = match config.codec {
        CodecChoice::Fixed(_) => spinner("encode"),
        CodecChoice::MaxError(_) => {
            let bar = bar_at_most("encode", "candidates");
            bar.set_length(encode::default_candidates().len() as u64);
            bar
        }
    };
    let (encoded, h_error, chosen_by) = match config.codec {
        CodecChoice::Fixed(kind) => {
            progress(&format!("encoding with {kind}"));
            let (e, err) = {
                let tp = channels_of(permuted);
                let e = encode::encode(kind, tp, n)?;
                let err = (!b0_samples.is_empty()).then(|| {
                    let reference = encode::exact_products(tp, n, &b0_samples);
                    encode::h_error(&e, &reference, &b0_samples)
                });
                (e, err)
            };
            let (e, err) = match err {
                Some(err0) if kind.log_params().is_some() => {
                    scale_columns(permuted, &scales, n);
                    let tp = channels_of(permuted);
                    let mut e1 = encode::encode(kind, tp, n)?;
                    let reference = encode::exact_products(tp, n, &scaled_samples);
                    let err1 = encode::h_error(&e1, &reference, &scaled_samples);
                    progress(&format!(
                        "  H error {:.3} %, with columns scaled by patch area {:.3} %",
                        100.0 * err0,
                        100.0 * err1
                    ));
                    if err1 < err0 {
                        e1.col_scale = scales;
                        (e1, Some(err1))
                    } else {
                        (e, Some(err0))
                    }
                }
                other => (e, other),
            };
            (e, err, "fixed".to_string())
        }
        CodecChoice::MaxError(max) => {
            progress(&format!(
                "choosing the cheapest codec with H error ≤ {max} ({} candidates, then with \
                 columns scaled by patch area)",
                encode::default_candidates().len()
            ));
            let (k0, e0, err0) = encode::choose_with(
                channels_of(permuted),
                n,
                &b0_samples,
                max,
                &[],
                encode::estimate_stride(n),
                &mut |kind, err, bpe, how| {
                    sp.inc(1);
                    progress(&format!(
                        "  {kind}: H error {:.3} %{}, {bpe:.4} bytes/entry",
                        100.0 * err,
                        estimated(how)
                    ))
                },
            )?;
            // Scaled, the log settings expected to cost no more than the
            // plain choice.
            let cheaper = encode::measure::log_candidates_no_dearer_than(k0);
            let scaled = if cheaper.is_empty() {
                None
            } else {
                sp.set_length(sp.position() + cheaper.len() as u64);
                scale_columns(permuted, &scales, n);
                match encode::choose_with(
                    channels_of(permuted),
                    n,
                    &scaled_samples,
                    max,
                    &cheaper,
                    encode::estimate_stride(n),
                    &mut |kind, err, bpe, how| {
                        sp.inc(1);
                        progress(&format!(
                            "  {kind}, columns scaled: H error {:.3} %{}, {bpe:.4} bytes/entry",
                            100.0 * err,
                            estimated(how)
                        ))
                    },
                ) {
                    Ok(chosen) => Some(chosen),
                    // No scaled setting within the bound: the plain one stays.
                    Err(encode::measure::ChooseError::NoCandidate { .. }) => None,
                    Err(e) => return Err(e.into()),
                }
            };
            match scaled {
                // The cheaper matrix, or at equal bytes the smaller error;
                // the scales' 4 bytes per patch (4/n bytes per entry) are
                // not held against it.
                Some((_, mut e1, err1))
                    if e1.bytes_total() < e0.bytes_total()
                        || (e1.bytes_total() == e0.bytes_total() && err1 < err0) =>
                {
                    e1.col_scale = scales;
                    (e1, Some(err1), format!("max-error {max}, columns scaled"))
                }
                _ => (e0, Some(err0), format!("max-error {max}")),
            }
        }
    };
    sp.finish_and_clear();
    let summary = CodecSummary::of(&encoded, chosen_by, h_error, b0_samples.len());
    Ok(Encoding {
        encoded,
        summary,
        error_lights: b0_samples.len() as u64,
    })
}

/// How a progress line qualifies a candidate's error.
fn estimated(how: encode::Measured) -> String {
    match how {
        encode::Measured::Full { estimate: None } => String::new(),
        encode::Measured::Full { estimate: Some(e) } => format!(
            " (estimate {:.3} % ± {:.3}, margin {:.2})",
            100.0 * e.error,
            100.0 * e.std_error,
            e.margin()
        ),
        encode::Measured::Estimated { stride, margin } => format!(
            " (estimated on 1 row of tiles in {stride}: above {margin:.2} × the bound, rejected)"
        ),
    }
}

/// `B0 = ρ ∘ D + E` (f32, per channel) for `count` seeded random lights
/// ([`direct::random_lights`] with [`ERROR_LIGHTS_SEED`]), direct light with
/// shadows on the CPU, for the patches in matrix order.
pub fn error_samples(scene: &scene::Scene, patches: &[Patch], count: usize) -> Vec<[Vec<f32>; 3]> {
    direct::light_samples(scene, patches, count, ERROR_LIGHTS_SEED)
}

/// The column scales of a matrix whose patches have areas `area` (matrix
/// order): each area relative to the largest, so in (0, 1] (a patch of
/// zero area, which the voxelizer does not keep, would get the smallest
/// positive f32 rather than 0).
pub fn column_scales(area: &[f64]) -> Vec<f32> {
    let max = area.iter().cloned().fold(0.0f64, f64::max);
    if !(max > 0.0 && max.is_finite()) {
        return vec![1.0; area.len()];
    }
    area.iter()
        .map(|&a| ((a / max) as f32).max(f32::MIN_POSITIVE))
        .collect()
}

/// The three channels of a matrix held as 1 or 3 vectors.
fn channels_of(m: &[Vec<f32>]) -> [&[f32]; 3] {
    std::array::from_fn(|c| m[c.min(m.len() - 1)].as_slice())
}

/// Divides each column `j` of the n × n row-major channels `m` by `s[j]`,
/// in place.
fn scale_columns(m: &mut [Vec<f32>], s: &[f32], n: usize) {
    for c in m {
        c.par_chunks_mut(n.max(1)).for_each(|row| {
            for (v, s) in row.iter_mut().zip(s) {
                *v /= s;
            }
        });
    }
}
