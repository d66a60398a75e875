//! The near-field correction (`NEAR`): where a patch sees a neighbour up
//! close, the part of the neighbour it sees, not the neighbour's mean.
//!
//! `H = T̃ · B0` gives every patch `j` one exitance, its mean over its
//! region. Seen from far away that is exact to first order; seen from a
//! patch next to it, it is not: a capital just above a gallery floor whose
//! sunlit strip runs along the colonnade sees mostly that strip, which is
//! several times brighter than the floor patch's mean (on Sponza at 4.5k
//! patches the worst patches were 3–5× too dark for this reason alone,
//! `docs/accuracy.md`). The run time already knows the direct light at the
//! neighbour's sample points ([`super::surface`]), so the first reflection
//! can use them: for each receiver `i` and each near neighbour `j`, the bake
//! stores how many of `rays` cosine-distributed rays from `i`'s sample
//! points meet `j` nearest to each of `j`'s sample points (`c_ijk`, its
//! Voronoi cells on the real surface). The run time, with `b_jk = ρ_j
//! D_jk` the exitance at those points and `B0_j` their mean, forms
//!
//! `c_i = Σ_j Σ_k (c_ijk − C_ij s_jk) / rays · b_jk`,  `C_ij = Σ_k c_ijk`
//!
//! with `s_jk` the share of `j`'s area nearest its point `k` (its cell's
//! area; stored per patch). Each weight's sum over `k` is zero, so a
//! uniformly lit neighbour adds nothing and emission, uniform per patch,
//! needs none; and a neighbour that a receiver sees evenly by area (far
//! away) adds nothing either, whatever the cells' sizes — weighting by
//! `1/m` instead of `s_jk` would add the difference between the cells'
//! area-weighted mean of `b` and the plain mean `B0` uses, a bias with no
//! physical meaning (on Sponza's camera view it made the indirect image
//! darker). Then, and since `T = (I − Fρ)⁻¹ F`, the corrected irradiance
//! through all bounces is `H = T̃ · (B0 + ρ ∘ c) + c`: one sparse product
//! before the gather and one addition after it.
//!
//! Only links with `F̂_ij ≥` [`MIN_FORM_FACTOR`] are stored (by default):
//! storing every link would take several times the compressed matrix
//! (Sponza at 1k patches: 2.6 MB against 0.36 MB and a 0.8 MB matrix). The
//! dropped links are not uniform views, though: on Sponza the sunlit part
//! of a floor patch lies in the open, seen from afar, and its shaded part
//! under the arcades is seen by the near neighbours, so keeping only the
//! near links' deviations lost light (Sponza at 1k patches: the first
//! reflection −3.4 % against the path tracer, +0.5 % with every link
//! stored). So each patch `j` also stores its **far weights** `q_jk`: how
//! the rays that meet it from receivers *without* a stored link spread
//! over its cells, weighted by those receivers' areas (by reciprocity, how
//! much of each cell's light leaves towards them). Every dropped link's
//! deviation `(c_ijk − C_ij s_jk)` is then taken as `C_ij (q_jk − s_jk)`,
//! their aggregate shape, which the gather carries as a change of `j`'s
//! exitance, `δ_j = Σ_k (q_jk − s_jk) b_jk`; the stored links deviate
//! from the same far view, `c_i = Σ_j Σ_k (c_ijk − C_ij q_jk) / rays ·
//! b_jk`, which for `F̂_ij ≈ C_ij` is the per-link formula above. Through
//! all bounces `H = T̃ · (B0 + δ + ρ ∘ c) + c`, the first reflection being
//! `F (B0 + δ) + c`. The weights of `δ` and of each link sum to zero over
//! `k`, so a uniformly lit patch adds nothing. A patch no dropped ray
//! meets has `q = s` and `δ = 0`, and so has every patch of a file made
//! before far weights were stored (read with `q = s`), as it was made.
//! (Taking the far view against the plain mean `B0` instead, `δ = Σ_k
//! (q_jk − 1/16) b_jk`, also replaces `B0` by the area-weighted mean of the
//! points: the first reflection measured +5.0 % there, and +4.7 % with
//! every link stored and that `δ`. On relief a cell holds steeper, dimmer
//! surfaces than its point, so area weights credit too much light to it.)
//!
//! A run time lighting fewer than [`SAMPLES_PER_PATCH`] points merges each
//! cell into its nearest lit point ([`NearField::groups`]).
//!
//! **At the receiver.** `H_i` is one value per patch, and the surface map
//! blends those values between patch centres; but a receiver's parts do
//! not see a near neighbour alike — the foot of a pillar sees the floor at
//! its foot under a much larger angle than the pillar's top does (on
//! Sponza at noon two thirds of the indirect image's squared error was one
//! such foot). So each stored link also counts its rays by the
//! *receiver's* cell they leave from (`r_ijg`, [`NearLink::from`]), and
//! each patch its rays cast per cell (`n_ig`, [`NearField::cast`]). These
//! cells are not the sample points' (the sender's cells above) but a
//! 4 × 4 grid over the receiver's voxel face ([`receiver_cell`]), so that
//! a pixel finds its values by bilinear lookup, as a lightmap's texels,
//! instead of searching 16 points per blended patch (measured on llvmpipe:
//! the shading pass 217 → 590 ms on Sponza at 640 × 480 with the points).
//! The run time adds in the receiver's cell `g` the deviation
//!
//! `Δ_ig = Σ_j (r_ijg / n_ig − R_ij / N_i) · B_j`, `R_ij = Σ_g r_ijg`, `N_i = Σ_g n_ig`
//!
//! with `B_j = B0_j + ρ_j H_j` the neighbour's whole exitance (its mean;
//! the sender's cells are the correction above). Weighted by the cells'
//! rays the deviations sum to zero, so `H_i` is unchanged and only its
//! distribution over the receiver is: pixels take `Δ` interpolated from
//! the points of the patches the surface map blends.
//!
//! **The sky.** A sky's irradiance is baked per patch (`SKYV`), so every
//! point of a patch would get its mean and the correction, whose weights
//! sum to zero over a patch's points, would add nothing to the sky's
//! light; yet a floor patch by a wall sees less sky at its wall side than
//! at its open side, as a shaded strip is dimmer than a sunlit one, and
//! its near neighbours see those sides. So the receiver's own rays are
//! also counted by the cell of its point nearest their origin: `o_jk`, the
//! fraction of the rays from cell `k` of patch `j` that leave the scene
//! (its cosine-weighted open sky; [`NearField::sky`]). The run time lights
//! the points with `D_sky,j · o_jk / Σ_k s_jk o_jk` — the patch's sky
//! irradiance shaped as its cells see the sky, with the same area mean —
//! and the correction then treats the sky like any light. The direction
//! of the sky a cell sees is the patch's (its octahedral cells): a cell
//! by a wall to the south sees less of the southern sky only, which this
//! scalar spreads over the whole sky.
//!
//! # Layout (little-endian)
//!
//! A 16-byte header — rays per receiver `u32`, links `m u32`, cells per
//! link `u32` (= [`SAMPLES_PER_PATCH`]), flags `u32` (bit 0: far weights
//! stored; the other bits 0) — then `n + 1` link starts (`u32`, receiver
//! `i`'s links are `starts[i]..starts[i+1]`), then `m` links of 36 bytes:
//! the neighbour (`u32`, file order), then its 16 cell counts (`u16`); then
//! per patch its 16 cell shares (`f32`, each ≥ 0, summing to 1); then, with
//! flag bit 0, per patch its 16 far weights (the same rules); then, with
//! flag bit 1, per patch its 16 cells' open sky fractions (`f32`, each in
//! 0..=1); then, with flag bit 2, per link its rays by the receiver's cell
//! (16 `u16`), and per patch its rays cast per cell (16 `u16`; a link's
//! count of a cell at most the cell's).

use super::surface::{PatchSamples, SAMPLES_PER_PATCH};
use crate::section_error::SectionError;

/// Links below this form factor (as the rays measure it) are not stored by
/// default (module doc): 2 % of a hemisphere. On Sponza at 4.5k patches it keeps
/// about 9 links per patch and, against keeping all, leaves 13.9 % instead
/// of 13.1 % relative RMS in the red channel's `H` (20.4 % without any).
pub const MIN_FORM_FACTOR: f64 = 0.02;

/// Bytes of one stored link.
pub const LINK_LEN: usize = 4 + 2 * SAMPLES_PER_PATCH;

/// Bytes of one patch's cell shares (and of its far weights).
pub const SHARES_LEN: u64 = 4 * SAMPLES_PER_PATCH as u64;

/// Header flag: far weights follow the shares.
const FLAG_FAR: u32 = 1;

/// Header flag: the cells' open sky fractions follow.
const FLAG_SKY: u32 = 2;

/// Header flag: the links' counts by the receiver's cell and each patch's
/// rays per cell follow.
const FLAG_RECEIVER: u32 = 4;

/// Bytes of one link's counts by the receiver's cell (and of one patch's
/// rays per cell).
const RECEIVER_LEN: usize = 2 * SAMPLES_PER_PATCH;

/// Receiver cells along each side of a patch's voxel face: 4 × 4, as many
/// as sample points (module doc, "At the receiver").
pub const RECEIVER_SIDE: usize = 4;
const _: () = assert!(RECEIVER_SIDE * RECEIVER_SIDE == SAMPLES_PER_PATCH);

/// The coordinates of `g` (a point in grid units: `(x − origin) / size`) in
/// the face of a patch whose voxel is `voxel` and facing axis `axis`: along
/// the axes `(axis + 1) % 3` and `(axis + 2) % 3` (the surface map's),
/// from its voxel's corner, 0..1 inside it.
pub fn face_coords(g: [f64; 3], voxel: [u32; 3], axis: usize) -> (f64, f64) {
    let (ua, va) = ((axis + 1) % 3, (axis + 2) % 3);
    (g[ua] - f64::from(voxel[ua]), g[va] - f64::from(voxel[va]))
}

/// The receiver cell (`0..16`, row-major in `v`) of face coordinates `(u, v)`
/// ([`face_coords`]), clamped into the face.
pub fn receiver_cell(u: f64, v: f64) -> usize {
    let side = RECEIVER_SIDE as f64;
    let k = |t: f64| ((t * side).floor().max(0.0) as usize).min(RECEIVER_SIDE - 1);
    k(u) + RECEIVER_SIDE * k(v)
}

/// Per-cell values `values` of one patch at face coordinates `(u, v)`:
/// bilinear between the cells' centres, extended linearly from the outer
/// centres to the face's edges and constant beyond (the CPU reference of
/// shade.frag's `at_cells`). Extending rather than holding the outer
/// centres' values follows a rise towards a face's edge (a pillar's foot):
/// Sponza at noon's indirect image 20.0 % from Mitsuba 3 held, 19.5 %
/// extended.
pub fn bilinear(values: &[f32], u: f64, v: f64) -> f32 {
    let side = RECEIVER_SIDE as f64;
    let t = |x: f64| (x * side - 0.5).clamp(-0.5, side - 0.5);
    let (tu, tv) = (t(u), t(v));
    let (iu, iv) = (
        (tu.floor().max(0.0) as usize).min(RECEIVER_SIDE - 2),
        (tv.floor().max(0.0) as usize).min(RECEIVER_SIDE - 2),
    );
    let (fu, fv) = ((tu - iu as f64) as f32, (tv - iv as f64) as f32);
    let at = |a: usize, b: usize| values[(iu + a) + RECEIVER_SIDE * (iv + b)];
    let row0 = at(0, 0) + fu * (at(1, 0) - at(0, 0));
    let row1 = at(0, 1) + fu * (at(1, 1) - at(0, 1));
    row0 + fv * (row1 - row0)
}

/// One receiver's view of one near neighbour.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NearLink {
    /// The neighbour.
    pub patch: u32,
    /// Rays from the receiver meeting the neighbour nearest each of its
    /// sample points.
    pub counts: [u16; SAMPLES_PER_PATCH],
    /// The same rays by the receiver's cell they left from (all 0 in a
    /// file without them, [`NearField::cast`] then empty).
    pub from: [u16; SAMPLES_PER_PATCH],
}

/// The near-field correction of a bake (module doc). Empty (`rays == 0`)
/// for a bake made without it: the correction is then zero.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct NearField {
    /// Rays cast per receiver (all its sample points together).
    pub rays: u32,
    /// `n + 1` starts into `links` (empty when `rays == 0`: no correction
    /// has one representation, the default).
    pub starts: Vec<u32>,
    pub links: Vec<NearLink>,
    /// Per patch (empty when `rays == 0`): the share of its area in each
    /// sample point's cell.
    pub shares: Vec<[f32; SAMPLES_PER_PATCH]>,
    /// Per patch, or empty (files from before they were stored): how the
    /// rays from receivers without a stored link spread over its cells,
    /// area-weighted (module doc).
    pub far: Vec<[f32; SAMPLES_PER_PATCH]>,
    /// Per patch, or empty (files from before they were stored): the
    /// fraction of the rays from each of its cells that left the scene, its
    /// cells' open sky (module doc, "The sky").
    pub sky: Vec<[f32; SAMPLES_PER_PATCH]>,
    /// Per patch, or empty (files from before they were stored, whose
    /// links' `from` are 0): the rays cast from each of its cells (module
    /// doc, "At the receiver").
    pub cast: Vec<[u16; SAMPLES_PER_PATCH]>,
}

impl NearField {
    /// No correction (for any patch count): the default value.
    pub fn none() -> NearField {
        NearField::default()
    }

    /// Whether there is anything to apply.
    pub fn is_empty(&self) -> bool {
        self.rays == 0 || self.links.is_empty()
    }

    /// Receiver `i`'s links (none when there is no correction).
    pub fn links_of(&self, i: usize) -> &[NearLink] {
        if self.rays == 0 {
            return &[];
        }
        &self.links[self.starts[i] as usize..self.starts[i + 1] as usize]
    }

    /// Patch `j`'s far weights: the stored ones, or for a file without them
    /// its area shares (the correction as such files were made).
    pub fn far_of(&self, j: usize) -> &[f32; SAMPLES_PER_PATCH] {
        self.far.get(j).unwrap_or(&self.shares[j])
    }

    /// The bytes of `NEAR`.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(16 + 4 * self.starts.len() + LINK_LEN * self.links.len());
        for v in [
            self.rays,
            self.links.len() as u32,
            SAMPLES_PER_PATCH as u32,
            if self.far.is_empty() { 0 } else { FLAG_FAR }
                | if self.sky.is_empty() { 0 } else { FLAG_SKY }
                | if self.cast.is_empty() {
                    0
                } else {
                    FLAG_RECEIVER
                },
        ] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for s in &self.starts {
            out.extend_from_slice(&s.to_le_bytes());
        }
        for l in &self.links {
            out.extend_from_slice(&l.patch.to_le_bytes());
            for c in l.counts {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
        for s in self
            .shares
            .iter()
            .chain(&self.far)
            .chain(&self.sky)
            .flatten()
        {
            out.extend_from_slice(&s.to_le_bytes());
        }
        if !self.cast.is_empty() {
            let from = self.links.iter().map(|l| &l.from);
            for c in from.chain(&self.cast).flatten() {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
        out
    }

    /// Reads `NEAR` for a file of `n` patches; every length, index and
    /// count is checked ([`NearField::check`]).
    pub fn from_bytes(b: &[u8], n: usize) -> Result<NearField, SectionError> {
        let u32_at = |at: usize| u32::from_le_bytes(b[at..at + 4].try_into().expect("4 bytes"));
        if b.len() < 16 {
            return Err(SectionError::Truncated {
                what: "header",
                need: 16,
                at: 0,
                left: b.len() as u64,
            });
        }
        let (rays, m, cells, flags) = (u32_at(0), u32_at(4) as usize, u32_at(8), u32_at(12));
        if cells as usize != SAMPLES_PER_PATCH {
            return Err(SectionError::Unsupported(format!(
                "{cells} cells per link, this build reads {SAMPLES_PER_PATCH}"
            )));
        }
        if flags & !(FLAG_FAR | FLAG_SKY | FLAG_RECEIVER) != 0 {
            return Err(SectionError::Unsupported(format!(
                "flags are {flags:#x}, only bits 0 to 2 are defined"
            )));
        }
        let (has_far, has_sky) = (flags & FLAG_FAR != 0, flags & FLAG_SKY != 0);
        let has_receiver = flags & FLAG_RECEIVER != 0;
        let per_patch = 1 + u64::from(has_far) + u64::from(has_sky);
        let want = (n as u64 + 1) * 4
            + m as u64 * LINK_LEN as u64
            + 16
            + per_patch * n as u64 * SHARES_LEN
            + u64::from(has_receiver) * (m + n) as u64 * RECEIVER_LEN as u64;
        if b.len() as u64 != want {
            return Err(SectionError::Length {
                found: b.len() as u64,
                expected: want,
                layout: format!("{n} patches and {m} links"),
            });
        }
        let starts: Vec<u32> = (0..=n).map(|i| u32_at(16 + 4 * i)).collect();
        let base = 16 + 4 * (n + 1);
        let u16s_at = |at: usize| -> [u16; SAMPLES_PER_PATCH] {
            std::array::from_fn(|k| u16::from_le_bytes([b[at + 2 * k], b[at + 1 + 2 * k]]))
        };
        // The receiver's counts, when stored, follow every per-patch row.
        let receiver = base + LINK_LEN * m + per_patch as usize * n * SHARES_LEN as usize;
        let links = (0..m)
            .map(|l| {
                let at = base + LINK_LEN * l;
                NearLink {
                    patch: u32_at(at),
                    counts: u16s_at(at + 4),
                    from: if has_receiver {
                        u16s_at(receiver + RECEIVER_LEN * l)
                    } else {
                        [0; SAMPLES_PER_PATCH]
                    },
                }
            })
            .collect();
        let cast = if has_receiver {
            (0..n)
                .map(|j| u16s_at(receiver + RECEIVER_LEN * (m + j)))
                .collect()
        } else {
            Vec::new()
        };
        let base = base + LINK_LEN * m;
        let f32_at = |at: usize| f32::from_le_bytes(b[at..at + 4].try_into().expect("4 bytes"));
        let per_patch_at = |base: usize| -> Vec<[f32; SAMPLES_PER_PATCH]> {
            (0..n)
                .map(|j| std::array::from_fn(|k| f32_at(base + SHARES_LEN as usize * j + 4 * k)))
                .collect()
        };
        let shares = per_patch_at(base);
        let far = if has_far {
            per_patch_at(base + SHARES_LEN as usize * n)
        } else {
            Vec::new()
        };
        let sky = if has_sky {
            per_patch_at(base + SHARES_LEN as usize * n * (1 + usize::from(has_far)))
        } else {
            Vec::new()
        };
        let nf = NearField {
            rays,
            starts,
            links,
            shares,
            far,
            sky,
            cast,
        };
        nf.check(n)?;
        Ok(nf)
    }

    /// Checks the starts (from 0, non-decreasing, ending at the link
    /// count), the neighbours (in range, not the receiver), and that no
    /// receiver's counts exceed its rays.
    pub fn check(&self, n: usize) -> Result<(), SectionError> {
        if self.rays == 0 {
            // No correction (the default value, or a bake made without).
            return if self.links.is_empty() {
                Ok(())
            } else {
                Err(SectionError::Invalid(format!(
                    "{} links stored for 0 rays",
                    self.links.len()
                )))
            };
        }
        if self.starts.len() != n + 1 || self.shares.len() != n {
            return Err(SectionError::Invalid(format!(
                "{} link starts and {} cell shares for {n} patches ({} and {n} expected)",
                self.starts.len(),
                self.shares.len(),
                n + 1
            )));
        }
        if !self.far.is_empty() && self.far.len() != n {
            return Err(SectionError::Invalid(format!(
                "{} far weights for {n} patches",
                self.far.len()
            )));
        }
        if !self.sky.is_empty() && self.sky.len() != n {
            return Err(SectionError::Invalid(format!(
                "{} open sky fractions for {n} patches",
                self.sky.len()
            )));
        }
        if !self.cast.is_empty() && self.cast.len() != n {
            return Err(SectionError::Invalid(format!(
                "{} patches' rays per cell for {n} patches",
                self.cast.len()
            )));
        }
        for (j, o) in self.sky.iter().enumerate() {
            if o.iter().any(|v| !(0.0..=1.0).contains(v)) {
                return Err(SectionError::Invalid(format!(
                    "patch {j}: open sky fractions {o:?} are not numbers in 0..=1"
                )));
            }
        }
        let named = [("cell shares", &self.shares), ("far weights", &self.far)];
        for (what, rows) in named {
            for (j, s) in rows.iter().enumerate() {
                let sum: f64 = s.iter().map(|&v| v as f64).sum();
                if s.iter().any(|v| !(v.is_finite() && *v >= 0.0)) || (sum - 1.0).abs() > 1e-4 {
                    return Err(SectionError::Invalid(format!(
                        "patch {j}: {what} {s:?} are not finite numbers ≥ 0 summing to 1"
                    )));
                }
            }
        }
        if self.starts[0] != 0 || self.starts[n] as usize != self.links.len() {
            return Err(SectionError::Invalid(format!(
                "link starts run from {} to {}, expected 0 to {}",
                self.starts[0],
                self.starts[n],
                self.links.len()
            )));
        }
        for i in 0..n {
            let (a, b) = (self.starts[i], self.starts[i + 1]);
            if b < a {
                return Err(SectionError::Invalid(format!(
                    "patch {i}: link starts decrease ({a} then {b})"
                )));
            }
            let mut total = 0u64;
            for l in &self.links[a as usize..b as usize] {
                if l.patch as usize >= n || l.patch as usize == i {
                    return Err(SectionError::Invalid(format!(
                        "patch {i}: neighbour {} out of range or itself",
                        l.patch
                    )));
                }
                total += l.counts.iter().map(|&c| c as u64).sum::<u64>();
                if let Some(cast) = self.cast.get(i) {
                    if let Some(g) = (0..SAMPLES_PER_PATCH).find(|&g| l.from[g] > cast[g]) {
                        return Err(SectionError::Invalid(format!(
                            "patch {i}: its link to {} counts {} rays from cell {g}, which \
                             cast {}",
                            l.patch, l.from[g], cast[g]
                        )));
                    }
                }
            }
            if total > self.rays as u64 {
                return Err(SectionError::Invalid(format!(
                    "patch {i}: its links count {total} rays of {}",
                    self.rays
                )));
            }
        }
        Ok(())
    }

    /// The same correction in matrix order: receiver `r` is file patch
    /// `order[r]`, neighbours renumbered by `new_of[old]`.
    pub fn reordered(&self, order: &[u32], new_of: &[u32]) -> NearField {
        if self.rays == 0 {
            return NearField::none();
        }
        let mut out = NearField {
            rays: self.rays,
            starts: Vec::with_capacity(order.len() + 1),
            links: Vec::with_capacity(self.links.len()),
            shares: order.iter().map(|&o| self.shares[o as usize]).collect(),
            far: if self.far.is_empty() {
                Vec::new()
            } else {
                order.iter().map(|&o| self.far[o as usize]).collect()
            },
            sky: if self.sky.is_empty() {
                Vec::new()
            } else {
                order.iter().map(|&o| self.sky[o as usize]).collect()
            },
            cast: if self.cast.is_empty() {
                Vec::new()
            } else {
                order.iter().map(|&o| self.cast[o as usize]).collect()
            },
        };
        out.starts.push(0);
        for &o in order {
            for l in self.links_of(o as usize) {
                out.links.push(NearLink {
                    patch: new_of[l.patch as usize],
                    ..*l
                });
            }
            out.starts.push(out.links.len() as u32);
        }
        out
    }

    /// For a run time lighting the first `m` sample points of each patch:
    /// per patch, the lit point (`0..m`) each of the 16 cells merges into,
    /// the nearest one (cells `k < m` are their own).
    pub fn groups(samples: &PatchSamples, n: usize, m: usize) -> Vec<[u8; SAMPLES_PER_PATCH]> {
        let m = m.clamp(1, SAMPLES_PER_PATCH);
        (0..n)
            .map(|j| {
                let p = |k: usize| samples.position[j * SAMPLES_PER_PATCH + k];
                std::array::from_fn(|k| {
                    if k < m {
                        return k as u8;
                    }
                    let d2 = |g: usize| {
                        (0..3)
                            .map(|c| (p(k)[c] as f64 - p(g)[c] as f64).powi(2))
                            .sum::<f64>()
                    };
                    (0..m)
                        .min_by(|&a, &b| d2(a).total_cmp(&d2(b)))
                        .expect("m >= 1") as u8
                })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Cell values of a plane `a + b u + c v` (taken at the cells'
    /// centres) come back as that plane anywhere in the face, edges
    /// included (the lookup extends linearly to them), and constant beyond.
    #[test]
    fn the_cells_lookup_reproduces_a_plane() {
        let plane = |u: f64, v: f64| 0.5 + 2.0 * u - 3.0 * v;
        let side = RECEIVER_SIDE as f64;
        let values: Vec<f32> = (0..SAMPLES_PER_PATCH)
            .map(|g| {
                let (u, v) = (
                    ((g % RECEIVER_SIDE) as f64 + 0.5) / side,
                    ((g / RECEIVER_SIDE) as f64 + 0.5) / side,
                );
                plane(u, v) as f32
            })
            .collect();
        for (u, v) in [
            (0.0, 0.0),
            (0.3, 0.7),
            (1.0, 0.5),
            (0.125, 0.875),
            (0.99, 0.01),
        ] {
            let got = f64::from(bilinear(&values, u, v));
            assert!((got - plane(u, v)).abs() < 1e-5, "({u}, {v}): {got}");
        }
        assert_eq!(bilinear(&values, 1.4, -0.2), bilinear(&values, 1.0, 0.0));
        assert_eq!(receiver_cell(0.3, 0.7), 1 + 4 * 2);
        assert_eq!(receiver_cell(-0.1, 1.2), 4 * 3);
    }
}
