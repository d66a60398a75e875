//! The near-field correction at run time ([`crate::bakefile::near_field`]
//! defines it): `c = W · b`, with `b_jg = ρ_j D_jg` the exitance at patch
//! `j`'s lit sample points and `W` the bake's cell counts turned into
//! weights that sum to zero per link; then `H = T̃ · (B0 + ρ ∘ c) + c`.
//! The CPU reference of `glsl/near_field.comp`.

use crate::bakefile::near_field::NearField;
use crate::bakefile::surface::{PatchSamples, SAMPLES_PER_PATCH};
use rayon::prelude::*;

/// The correction's weights for a run time lighting `m` sample points per
/// patch.
#[derive(Clone, Debug, Default)]
pub struct NearFieldWeights {
    /// Sample points lit per patch.
    pub m: usize,
    /// `n + 1` starts into `patch` and `weights`.
    pub starts: Vec<u32>,
    /// Per link: the neighbour (matrix order).
    pub patch: Vec<u32>,
    /// Per link: the weight of each of the neighbour's `m` lit points
    /// (slots `m..16` are 0), `(c_g − C s_g) / rays` over the cells merged
    /// into point `g`.
    pub weights: Vec<[f32; SAMPLES_PER_PATCH]>,
}

impl NearFieldWeights {
    /// The weights of `nf` (matrix order) for `m` lit points of `samples`
    /// (cells merge into their nearest lit point, [`NearField::groups`]).
    pub fn new(nf: &NearField, samples: &PatchSamples, n: usize, m: usize) -> NearFieldWeights {
        let m = m.clamp(1, SAMPLES_PER_PATCH);
        if nf.is_empty() {
            return NearFieldWeights {
                m,
                starts: vec![0; n + 1],
                ..Default::default()
            };
        }
        let groups = NearField::groups(samples, n, m);
        let rays = nf.rays as f64;
        let mut out = NearFieldWeights {
            m,
            starts: nf.starts.clone(),
            patch: Vec::with_capacity(nf.links.len()),
            weights: Vec::with_capacity(nf.links.len()),
        };
        for l in &nf.links {
            let j = l.patch as usize;
            let total: f64 = l.counts.iter().map(|&v| v as f64).sum();
            let mut w = [0.0f64; SAMPLES_PER_PATCH];
            for (k, &v) in l.counts.iter().enumerate() {
                w[groups[j][k] as usize] += v as f64 - total * nf.shares[j][k] as f64;
            }
            out.patch.push(l.patch);
            out.weights
                .push(std::array::from_fn(|g| (w[g] / rays) as f32));
        }
        out
    }

    /// Whether the correction is identically zero.
    pub fn is_empty(&self) -> bool {
        self.patch.is_empty()
    }

    /// Links stored.
    pub fn links(&self) -> usize {
        self.patch.len()
    }

    /// `c = W · b` (three channels, `n` each) from `b` (three channels,
    /// `n × m` each: patch `j`'s lit point `g` at `j m + g`). Each receiver
    /// sums its links in stored order in f32, as the shader does.
    pub fn correction(&self, b: &[Vec<f32>; 3]) -> [Vec<f32>; 3] {
        let n = self.starts.len() - 1;
        let m = self.m;
        let rows: Vec<[f32; 3]> = (0..n)
            .into_par_iter()
            .map(|i| {
                let mut c = [0.0f32; 3];
                for l in self.starts[i] as usize..self.starts[i + 1] as usize {
                    let base = self.patch[l] as usize * m;
                    let w = &self.weights[l];
                    for (ch, cc) in c.iter_mut().enumerate() {
                        let mut s = 0.0f32;
                        for g in 0..m {
                            s += w[g] * b[ch][base + g];
                        }
                        *cc += s;
                    }
                }
                c
            })
            .collect();
        std::array::from_fn(|ch| rows.iter().map(|r| r[ch]).collect())
    }
}
