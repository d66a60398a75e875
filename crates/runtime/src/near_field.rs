//! The near-field correction at run time ([`radiosity_bakefile::near_field`]
//! defines it): `c = W · b`, with `b_jg = ρ_j D_jg` the exitance at patch
//! `j`'s lit sample points and `W` the bake's cell counts turned into
//! weights that sum to zero per link; `δ_j = Σ_g e_jg b_jg`, how the
//! receivers without a stored link see each patch differently from its
//! area shares (weights `e`, far weights less shares, summing to zero); then
//! `H = T̃ · (B0 + δ + ρ ∘ c) + c`. The CPU reference of
//! `crates/gl/glsl/near_field.comp`.

use radiosity_bakefile::baked::BakedPatch;
use radiosity_bakefile::near_field::NearField;
use radiosity_bakefile::surface::{PatchSamples, SAMPLES_PER_PATCH};
use rayon::prelude::*;

/// Patches per parallel task of [`NearFieldWeights::correction`]: a patch
/// is a few dozen multiply-adds, and one task per patch spent more in the
/// scheduler than in them.
const PATCHES_PER_TASK: usize = 256;

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
    /// (slots `m..16` are 0), `(c_g − C q_g) / rays` (`q` the far weights,
    /// the area shares for a file without them) over the cells merged into
    /// point `g`.
    pub weights: Vec<[f32; SAMPLES_PER_PATCH]>,
    /// Per patch (empty when the bake stores no far weights): the weight
    /// of each of its `m` lit points in `δ`, its far weights less its area
    /// shares, over the cells merged into the point (slots `m..16` are 0).
    pub own: Vec<[f32; SAMPLES_PER_PATCH]>,
    /// Per patch (empty when the bake stores no open sky per cell): the
    /// factor of each of its `m` lit points on the patch's sky irradiance,
    /// `ō_g / Σ_k s_k o_k` with `ō_g` the share-weighted mean open sky of
    /// the cells merged into point `g` (slots `m..16` are 0;
    /// [`radiosity_bakefile::near_field`], "The sky"). Their share-weighted
    /// mean is 1.
    pub sky: Vec<[f32; SAMPLES_PER_PATCH]>,
    /// Per link (empty when the bake stores no counts by the receiver's
    /// cell): the weight of the neighbour's exitance in each of the
    /// receiver's 16 face cells, `r_ijg / n_ig − R_ij / N_i` (a cell no ray
    /// left from takes its nearest cell's)
    /// ([`radiosity_bakefile::near_field`], "At the receiver").
    pub receiver: Vec<[f32; SAMPLES_PER_PATCH]>,
}

/// One term's near-field correction.
#[derive(Clone, Debug)]
pub struct NearTerms {
    /// `c`, irradiance (three channels, `n` each): added to `H` after the
    /// gather, and as `ρ ∘ c` to its input.
    pub c: [Vec<f32>; 3],
    /// `δ`, exitance (three channels, `n` each; zeros without far
    /// weights): added to the gather's input.
    pub delta: [Vec<f32>; 3],
}

impl NearTerms {
    /// The gather's input `B0 + δ + ρ ∘ c` (`patches` in matrix order for
    /// `ρ`), summed in this order in f32, as the shader does.
    pub fn gather_input(&self, b0: &[Vec<f32>; 3], patches: &[BakedPatch]) -> [Vec<f32>; 3] {
        std::array::from_fn(|ch| {
            b0[ch]
                .iter()
                .zip(&self.delta[ch])
                .zip(&self.c[ch])
                .zip(patches)
                .map(|(((&b, &d), &c), p)| b + d + p.albedo[ch] * c)
                .collect()
        })
    }
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
            own: Vec::new(),
            sky: Vec::new(),
            receiver: Vec::new(),
        };
        for l in &nf.links {
            let j = l.patch as usize;
            let total: f64 = l.counts.iter().map(|&v| v as f64).sum();
            let q = nf.far_of(j);
            let mut w = [0.0f64; SAMPLES_PER_PATCH];
            for (k, &v) in l.counts.iter().enumerate() {
                w[groups[j][k] as usize] += v as f64 - total * q[k] as f64;
            }
            out.patch.push(l.patch);
            out.weights
                .push(std::array::from_fn(|g| (w[g] / rays) as f32));
        }
        if !nf.far.is_empty() {
            out.own = (0..n)
                .map(|j| {
                    let mut e = [0.0f64; SAMPLES_PER_PATCH];
                    for (k, (&q, &s)) in nf.far[j].iter().zip(&nf.shares[j]).enumerate() {
                        e[groups[j][k] as usize] += q as f64 - s as f64;
                    }
                    e.map(|v| v as f32)
                })
                .collect();
        }
        if !nf.cast.is_empty() {
            out.receiver = Vec::with_capacity(nf.links.len());
            for (i, cast) in nf.cast.iter().enumerate() {
                let total: f64 = cast.iter().map(|&v| f64::from(v)).sum();
                // A cell no ray left from (the face beyond the patch's
                // pieces) takes its nearest cell's weight, so that the
                // lookup between cells blends values, not zeros.
                let fill = fill_of(cast);
                for l in nf.links_of(i) {
                    let from: f64 = l.from.iter().map(|&v| f64::from(v)).sum();
                    let mean = if total > 0.0 { from / total } else { 0.0 };
                    let w: [f32; SAMPLES_PER_PATCH] = std::array::from_fn(|g| {
                        if cast[g] == 0 {
                            0.0
                        } else {
                            (f64::from(l.from[g]) / f64::from(cast[g]) - mean) as f32
                        }
                    });
                    out.receiver.push(std::array::from_fn(|g| w[fill[g]]));
                }
            }
        }
        if !nf.sky.is_empty() {
            out.sky = (0..n)
                .map(|j| sky_factors(&nf.sky[j], &nf.shares[j], &groups[j], m))
                .collect();
        }
        out
    }

    /// The sky's irradiance at the lit points (three channels, `n × m`, the
    /// layout of [`NearFieldWeights::correction`]'s input) from its
    /// per-patch value `d` (matrix order): `d_j` times point `g`'s factor
    /// ([`NearFieldWeights::sky`]); `None` when the bake stores no open sky
    /// per cell (every point would take `d_j`, which the correction
    /// ignores).
    pub fn sky_points(&self, d: &[Vec<f32>; 3]) -> Option<[Vec<f32>; 3]> {
        (!self.sky.is_empty()).then(|| sky_points(&self.sky, self.m, d))
    }

    /// The deviation `Δ` of `H` in each receiver's 16 face cells (three
    /// channels, `n × 16`: patch `i`'s cell `g` at `16 i + g`) from the
    /// frame's `B0` and `H` (matrix order), its near neighbours' whole
    /// exitance `B0_j + ρ_j H_j` weighted by [`NearFieldWeights::receiver`]
    /// (summed per receiver in link order, f32, as the shader does);
    /// `None` when the bake stores no counts by the receiver's cell.
    pub fn receiver_deviation(
        &self,
        b0: &[Vec<f32>; 3],
        h: &[Vec<f32>; 3],
        patches: &[BakedPatch],
    ) -> Option<[Vec<f32>; 3]> {
        if self.receiver.is_empty() {
            return None;
        }
        let n = self.starts.len() - 1;
        let rows: Vec<[[f32; SAMPLES_PER_PATCH]; 3]> = (0..n)
            .into_par_iter()
            .with_min_len(PATCHES_PER_TASK)
            .map(|i| {
                let mut d = [[0.0f32; SAMPLES_PER_PATCH]; 3];
                for l in self.starts[i] as usize..self.starts[i + 1] as usize {
                    let j = self.patch[l] as usize;
                    let u = &self.receiver[l];
                    for (ch, dc) in d.iter_mut().enumerate() {
                        let b = b0[ch][j] + patches[j].albedo[ch] * h[ch][j];
                        for (x, &w) in dc.iter_mut().zip(u) {
                            *x += w * b;
                        }
                    }
                }
                d
            })
            .collect();
        Some(std::array::from_fn(|ch| {
            rows.iter().flat_map(|r| r[ch]).collect()
        }))
    }

    /// Whether the correction is identically zero.
    pub fn is_empty(&self) -> bool {
        self.patch.is_empty() && self.own.is_empty()
    }

    /// Links stored.
    pub fn links(&self) -> usize {
        self.patch.len()
    }

    /// `c = W · b` and `δ` (module doc) from `b` (three channels, `n × m`
    /// each: patch `j`'s lit point `g` at `j m + g`). Each receiver sums
    /// its links in stored order in f32, as the shader does, and its own
    /// points in order.
    pub fn correction(&self, b: &[Vec<f32>; 3]) -> NearTerms {
        let m = self.m;
        self.correction_with(
            |ch, j, g| b[ch][j * m + g],
            |j| {
                b.iter()
                    .any(|ch| ch[j * m..(j + 1) * m].iter().any(|&v| v != 0.0))
            },
        )
    }

    /// [`NearFieldWeights::correction`] of the exitance `b = ρ_j d` at the
    /// lit points, from the irradiance `d` there (the layout of `b`) and
    /// the patches' albedos, without building `b`: each value is the same
    /// f32 product [`crate::direct::reflected_at_points`] forms,
    /// so the same bits. What a frame calls: a spot lighting a few per cent
    /// of the patches then costs a few per cent of the links and little
    /// else (the interior at 3,499 patches, per light, best of 500:
    /// 0.12–0.14 ms when `b` was built first and every patch tested in a
    /// second parallel pass, 0.06–0.075 ms so).
    pub fn correction_reflected(&self, d: &[Vec<f32>; 3], patches: &[BakedPatch]) -> NearTerms {
        let m = self.m;
        // A patch whose irradiance is 0 at every lit point has b = 0 there
        // (ρ · ±0 = ±0); one with some non-zero irradiance is taken as lit
        // even where ρ · d underflows or ρ is 0, which adds only exact
        // zeros (the skip's argument below).
        self.correction_with(
            |ch, j, g| patches[j].albedo[ch] * d[ch][j * m + g],
            |j| {
                d.iter().any(|ch| {
                    ch[j * m..(j + 1) * m]
                        .iter()
                        .fold(false, |a, &v| a | (v != 0.0))
                })
            },
        )
    }

    /// The correction with `b(ch, j, g)` the exitance of patch `j`'s lit
    /// point `g` in channel `ch`, and `lit(j)` true wherever some `b(·, j,
    /// ·)` is non-zero.
    fn correction_with(
        &self,
        b: impl Fn(usize, usize, usize) -> f32 + Sync,
        lit: impl Fn(usize) -> bool,
    ) -> NearTerms {
        let n = self.starts.len() - 1;
        let m = self.m;
        // The patches with some non-zero exitance at a lit point. An
        // unlit patch adds exactly +0 to every sum it enters (w · ±0 = ±0
        // summed onto a +0 start, and a sum that starts at +0 never
        // becomes −0), so its links and its own δ are skipped with the
        // same bits: a spot lighting 8 % of the interior's 3,499 patches
        // touches a tenth of the links. Found on the calling thread (a
        // pass over the lit points' values, shorter than handing it to
        // the pool).
        let lit: Vec<bool> = (0..n).map(lit).collect();
        let rows: Vec<([f32; 3], [f32; 3])> = (0..n)
            .into_par_iter()
            .with_min_len(PATCHES_PER_TASK)
            .map(|i| {
                let mut delta = [0.0f32; 3];
                if let Some(e) = self.own.get(i).filter(|_| lit[i]) {
                    for (ch, d) in delta.iter_mut().enumerate() {
                        for (g, &eg) in e[..m].iter().enumerate() {
                            *d += eg * b(ch, i, g);
                        }
                    }
                }
                let mut c = [0.0f32; 3];
                for l in self.starts[i] as usize..self.starts[i + 1] as usize {
                    let j = self.patch[l] as usize;
                    if !lit[j] {
                        continue;
                    }
                    let w = &self.weights[l];
                    for (ch, cc) in c.iter_mut().enumerate() {
                        let mut s = 0.0f32;
                        for (g, &wg) in w[..m].iter().enumerate() {
                            s += wg * b(ch, j, g);
                        }
                        *cc += s;
                    }
                }
                (c, delta)
            })
            .collect();
        NearTerms {
            c: std::array::from_fn(|ch| rows.iter().map(|r| r.0[ch]).collect()),
            delta: std::array::from_fn(|ch| rows.iter().map(|r| r.1[ch]).collect()),
        }
    }
}

/// The sky's irradiance at `m` lit points per patch from its per-patch
/// value `d` and each patch's point factors `factors`
/// ([`NearFieldWeights::sky_points`]; the GL renderer uploads the same).
pub fn sky_points(
    factors: &[[f32; SAMPLES_PER_PATCH]],
    m: usize,
    d: &[Vec<f32>; 3],
) -> [Vec<f32>; 3] {
    std::array::from_fn(|ch| {
        d[ch]
            .iter()
            .zip(factors)
            .flat_map(|(&v, f)| f[..m].iter().map(move |&x| v * x))
            .collect()
    })
}

/// For each receiver cell, the cell whose values it takes: itself when rays
/// left from it, else the nearest cell that cast some (grid distance, the
/// lowest index on ties; itself when none did).
fn fill_of(cast: &[u16; SAMPLES_PER_PATCH]) -> [usize; SAMPLES_PER_PATCH] {
    let side = radiosity_bakefile::near_field::RECEIVER_SIDE;
    std::array::from_fn(|g| {
        if cast[g] > 0 {
            return g;
        }
        let d2 = |k: usize| {
            let (a, b) = (
                (g % side) as i64 - (k % side) as i64,
                (g / side) as i64 - (k / side) as i64,
            );
            a * a + b * b
        };
        (0..SAMPLES_PER_PATCH)
            .filter(|&k| cast[k] > 0)
            .min_by_key(|&k| (d2(k), k))
            .unwrap_or(g)
    })
}

/// One patch's sky factors for `m` lit points ([`NearFieldWeights::sky`])
/// from its cells' open sky `o`, area shares `s` and lit point per cell
/// `group`; all 1 for a patch that sees no sky (its `D_sky` is then 0, or
/// the form factors' rays saw sky where these did not: no shape to give).
fn sky_factors(
    o: &[f32; SAMPLES_PER_PATCH],
    s: &[f32; SAMPLES_PER_PATCH],
    group: &[u8; SAMPLES_PER_PATCH],
    m: usize,
) -> [f32; SAMPLES_PER_PATCH] {
    let mean: f64 = o.iter().zip(s).map(|(&a, &b)| a as f64 * b as f64).sum();
    let (mut num, mut den) = ([0.0f64; SAMPLES_PER_PATCH], [0.0f64; SAMPLES_PER_PATCH]);
    for k in 0..SAMPLES_PER_PATCH {
        let g = group[k] as usize;
        num[g] += o[k] as f64 * s[k] as f64;
        den[g] += s[k] as f64;
    }
    std::array::from_fn(|g| {
        if g >= m {
            0.0
        } else if mean <= 0.0 || den[g] <= 0.0 {
            1.0
        } else {
            (num[g] / den[g] / mean) as f32
        }
    })
}
