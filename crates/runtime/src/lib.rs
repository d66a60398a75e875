//! The run time on the CPU: a baked scene lit by lights that move, with
//! indirect light that follows (docs/design.md, run time). It is the reference
//! the GL renderer is tested against and the fallback where GL is too slow.
//! It imports the core and the bake file's contract, never a bake stage.
//!
//! Per frame ([`Runtime::frame`]):
//! 1. direct irradiance `D` on every patch from its sample points, with
//!    shadows ([`direct`]);
//! 2. `B0 = ρ ∘ D + E`, `E` with each emissive material's run-time scale
//!    ([`emission`]);
//! 3. `H = T̃ · B0` straight from the compressed matrix ([`gather`]); with
//!    the bake's near-field correction `c` (and each patch's far-field
//!    exitance `B0 + δ`) from the exitance at the lit sample points,
//!    `H = T̃ · (B0 + δ + ρ ∘ c) + c` ([`near_field`]).
//!
//! **What a frame skips.** The products are kept per light and for the
//! emission: `H = T̃ E + Σ_l (T̃ (ρ ∘ D_l + δ_l + ρ ∘ c_l) + c_l)`, `c_l`
//! and `δ_l` the near-field correction of light `l`, each term the gather
//! of its own `B0` over that term's non-zero columns only. A frame recomputes the
//! terms whose light (or emission scales) changed — so moving one spot
//! light costs one direct pass for that light and one gather over the
//! columns it lights — and sums; when nothing changed, nothing is
//! computed. Every term is a fresh product, never an accumulation of
//! differences, so there is no drift over many frames: after any sequence
//! of changes `H` equals a full gather of the total `B0` up to the f32
//! rounding of the sum of terms. Each term keeps `D`, `B0` and `H` (36
//! bytes a patch); beyond [`RuntimeOptions::term_cache_bytes`] (512 MiB:
//! 3,640 lights at 4,096 patches, 227 at 65,535) consecutive lights share
//! a term, and a moved light recomputes its group.
//!
//! **Culling** ([`RuntimeOptions::cull`], off by default): each product
//! may also drop its lightest column groups, by `T̃`'s column sums times
//! the input's magnitude, within a stated fraction of its L1 norm
//! ([`ActiveColumns::culled`]); the frame's stats sum what was dropped.
//! Terms stay fresh products, so culling does not drift either; a frame
//! after the culling (or the sample-point) option changed recomputes
//! every term.
//!
//! Evaluating `H` at pixels ([`surface`]) and shading them ([`render`],
//! [`tonemap`]) complete the frame.
//!
//! ## Embedding it
//!
//! An application that draws the scene itself opens a bake (with the scene
//! it names, checked to be the one baked), calls [`Runtime::frame`] with
//! its lights, and reads the indirect light per patch or at a point of the
//! scene's triangles (`examples/embed.rs`; the GPU version, in a GL context
//! the application owns, is `examples/gl_embed.rs`):
//!
//! ```no_run
//! use radiosity_core::scene_config::Light;
//! use radiosity_runtime::{Runtime, RuntimeOptions};
//! use std::collections::BTreeMap;
//! use std::path::Path;
//! # fn main() -> Result<(), radiosity_runtime::open::OpenError> {
//! let mut rt = Runtime::open(Path::new("scene.rad"), None, RuntimeOptions::default())?;
//! let lights = [Light::Point { position: [1.0, 2.0, 0.5], intensity: [5.0; 3] }];
//! rt.frame(&lights, &BTreeMap::new()); // direct light on patches, B0, the gather
//! let per_patch = rt.h(); // indirect irradiance H per patch (RGB)
//! let at_point = rt.indirect_at(0, [0.5, 0.0, 0.5]); // H at a point of triangle 0
//! # let _ = (per_patch, at_point);
//! # Ok(())
//! # }
//! ```

// NaN-aware tests: `!(x > 0.0)` is true for NaN, which is the point.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod direct;
pub mod emission;
pub mod gather;
pub mod near_field;
pub mod open;
pub mod probes;
pub mod render;
pub mod sky;
pub mod surface;
pub mod texture;
pub mod tonemap;

use emission::Emission;
use gather::{ActiveColumns, CompressedGather, GatherStats};
use near_field::{NearFieldWeights, NearTerms};
use radiosity_bakefile::baked::Baked;
#[cfg(doc)]
use radiosity_bakefile::codec::Encoded;
use radiosity_core::direct::DirectLight;
use radiosity_core::scene::Scene;
use radiosity_core::scene_config::Light;
use std::collections::BTreeMap;
use std::time::Instant;

/// Options of the CPU run time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RuntimeOptions {
    /// Sample points per patch for direct light (1..=16; read at each
    /// frame: a change recomputes every term, and the near-field weights
    /// follow it).
    pub samples: usize,
    /// Skip zero columns of `B0` (off only to measure what it saves: the
    /// result is the same bit for bit).
    pub skip_columns: bool,
    /// Reuse the products of unchanged lights and frames (off: every frame
    /// recomputes everything).
    pub cache: bool,
    /// Use the AVX-512 gather where the CPU has it.
    pub simd: bool,
    /// Apply the bake's near-field correction ([`near_field`]; off only
    /// to measure what it does). Read when the run time is made.
    pub near_field: bool,
    /// Cull negligible columns: each product drops the column groups of
    /// least weight whose bound on its L1 norm sums to at most this
    /// fraction of the bound's total ([`ActiveColumns::culled`]; the
    /// weights are `T̃`'s column sums, computed once). 0 (the default):
    /// only zero columns are skipped, and the result is exact to the
    /// bit. Ignored when column skipping is off.
    pub cull: f64,
    /// Bytes the cached light terms may take: each term keeps `D`, `B0`
    /// and `H` (36 bytes a patch). With more lights than fit, consecutive
    /// lights share a term ([`lights_per_term`]), so that a lights file of
    /// thousands of lights cannot exhaust the memory; moving one light then
    /// recomputes its group.
    pub term_cache_bytes: usize,
}

/// The viewer's default [`RuntimeOptions::cull`]: on the interior and
/// Sponza at 4k patches, one spot light's term then reads 49–57 % of the column
/// groups of the exact one, for 0.11–0.19 % added RMS error of its `H`
/// (the Cornell box: 5.1 against 6.8 %, 0.09 %; README).
pub const VIEWER_CULL: f64 = 1e-3;

/// Bytes of one cached term per patch: `D`, `B0` and `H`, three f32
/// channels each.
pub const TERM_BYTES_PER_PATCH: usize = 36;

/// Lights per term for `lights` lights on `n` patches within `budget`
/// bytes of cached terms (module doc): 1 while every light's term fits,
/// else the fewest that keep the terms within the budget (at least one
/// term is always kept).
pub fn lights_per_term(lights: usize, n: usize, budget: usize) -> usize {
    let per_term = TERM_BYTES_PER_PATCH.saturating_mul(n.max(1));
    let terms = (budget / per_term).max(1);
    lights.div_ceil(terms).max(1)
}

impl Default for RuntimeOptions {
    fn default() -> Self {
        RuntimeOptions {
            samples: direct::DEFAULT_SAMPLES,
            skip_columns: true,
            cache: true,
            simd: true,
            near_field: true,
            cull: 0.0,
            term_cache_bytes: 512 << 20,
        }
    }
}

/// Times and counts of one frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameStats {
    /// Seconds of direct light, gathers (with the near-field correction's
    /// additions), and the whole frame.
    pub seconds_direct: f64,
    pub seconds_gather: f64,
    /// Seconds of the near-field correction (before the gathers).
    pub seconds_near_field: f64,
    /// Seconds of the probes' update (after the terms are summed; 0 when
    /// the bake has no probes or nothing changed).
    pub seconds_probes: f64,
    pub seconds_total: f64,
    /// Terms (lights, emission) recomputed, and reused.
    pub terms_computed: usize,
    pub terms_reused: usize,
    /// Nothing changed since the last frame: nothing was computed.
    pub unchanged: bool,
    /// Summed over the gathers of this frame.
    pub gather: GatherStats,
    /// Column groups active in the gathers of this frame, and their total.
    pub active_groups: usize,
    pub total_groups: usize,
}

/// One cached term of `H`.
#[derive(Clone, Debug)]
struct Term {
    /// The lights it holds (none for the emission term).
    lights: Vec<Light>,
    /// `D` of this light (zero for the emission term).
    d: [Vec<f32>; 3],
    b0: [Vec<f32>; 3],
    h: [Vec<f32>; 3],
}

/// A baked scene ready to be lit.
pub struct Runtime {
    pub baked: Baked,
    pub scene: Scene,
    pub direct: DirectLight,
    pub gather: CompressedGather,
    pub emission: Emission,
    /// The near-field correction's weights (empty when the bake has none
    /// or the option is off).
    pub near: NearFieldWeights,
    pub options: RuntimeOptions,
    /// `T̃`'s column sums per channel ([`Encoded::column_sums`]), for
    /// culling: computed at [`Runtime::new`] when culling is on, else at
    /// the first culled product.
    weights: std::sync::OnceLock<[Vec<f64>; 3]>,
    terms: Vec<Term>,
    emission_term: Option<(BTreeMap<String, f32>, Term)>,
    /// The sky lighting the frames ([`Runtime::set_sky`]).
    sky: Option<radiosity_core::sky::Sky>,
    /// The sky's term, for the sky it was computed for.
    sky_term: Option<(radiosity_core::sky::Sky, Term)>,
    d: [Vec<f32>; 3],
    b0: [Vec<f32>; 3],
    h: [Vec<f32>; 3],
    /// `Δ` in each patch's 16 face cells after the last frame
    /// ([`NearFieldWeights::receiver_deviation`]; `None` without).
    h_points: Option<[Vec<f32>; 3]>,
    /// The probes' coefficients after the last frame (empty without
    /// probes), and the sky's cell radiances they see.
    probe_sh: Vec<probes::Sh>,
    sky_cells: Option<Vec<[f32; 3]>>,
    /// The probes' entries decoded, the patches' albedos, and which probes
    /// the frames update (`None`: all).
    probe_decoded: probes::Decoded,
    probe_albedo: Vec<[f32; 3]>,
    probe_demand: Option<Vec<usize>>,
    frames: u64,
    /// The options the cached terms were computed with (culling, sample
    /// points): a frame after either changed recomputes every term.
    cached_with: (f64, usize),
}

impl Runtime {
    /// Prepares `baked` (from `scene`) for frames.
    pub fn new(baked: Baked, scene: Scene, options: RuntimeOptions) -> Runtime {
        let n = baked.patches.len();
        // The bake was made of the scene with back sides (everywhere when
        // two-sided, where the winding check chose otherwise): its sample
        // points and surface map index that scene's triangles.
        let scene = if baked.options.two_sided {
            scene.with_back_sides()
        } else {
            scene.with_back_sides_of(&baked.options.twinned)
        };
        let gather = CompressedGather::new(&baked.matrix, options.simd);
        let emission = Emission::new(&baked, &scene);
        let near = near_weights(&baked, options.near_field, options.samples);
        let weights = std::sync::OnceLock::new();
        if options.cull > 0.0 {
            let _ = weights.set(baked.matrix.column_sums());
        }
        Runtime {
            near,
            weights,
            direct: DirectLight::new(&scene),
            gather,
            emission,
            options,
            terms: Vec::new(),
            emission_term: None,
            sky: None,
            sky_term: None,
            d: std::array::from_fn(|_| vec![0.0; n]),
            b0: std::array::from_fn(|_| vec![0.0; n]),
            h: std::array::from_fn(|_| vec![0.0; n]),
            h_points: None,
            probe_sh: Vec::new(),
            sky_cells: None,
            probe_decoded: probes::Decoded::new(&baked.probes),
            probe_albedo: baked.patches.iter().map(|p| p.albedo).collect(),
            probe_demand: None,
            frames: 0,
            cached_with: (options.cull, options.samples),
            baked,
            scene,
        }
    }

    /// Patches.
    pub fn n(&self) -> usize {
        self.baked.patches.len()
    }

    /// The probes the frames keep current ([`Runtime::set_probe_demand`]).
    pub fn probe_demand(&self) -> Option<&[usize]> {
        self.probe_demand.as_deref()
    }

    /// Which probes a changed frame updates: `None` every probe (the
    /// default: the probe view, the GL comparison), `Some(list)` only
    /// those (the probes around the moving objects, which is all their
    /// shading reads; `probes::Lookup::needed`), `Some(vec![])` none (an
    /// application without moving objects: every probe costs 8–14 % of the
    /// gather on Sponza at 4k, `bench frame`). Probes newly demanded are
    /// updated at once from the last frame's light.
    pub fn set_probe_demand(&mut self, demand: Option<Vec<usize>>) {
        let fresh: Vec<usize> = match (&demand, &self.probe_demand) {
            (None, Some(_)) => (0..self.probe_decoded.len()).collect(),
            (Some(new), Some(old)) => new.iter().copied().filter(|p| !old.contains(p)).collect(),
            (Some(_), None) | (None, None) => Vec::new(),
        };
        self.probe_demand = demand;
        if self.frames > 0 && !fresh.is_empty() {
            self.update_probes(Some(&fresh));
        }
    }

    /// Updates the probes `which` (all when `None`) from the last frame's
    /// `B0`, `H` and sky: what a changed frame does for the demanded ones.
    pub fn update_probes(&mut self, which: Option<&[usize]>) {
        if self.probe_decoded.is_empty() {
            return;
        }
        // The emission apart: the probes see each emissive face's own
        // exitance, not its patch's area mean.
        let (e, emitted) = match &self.emission_term {
            Some((scales, t)) => (Some(&t.b0), probes::emitted(&self.scene.materials, scales)),
            None => (None, Vec::new()),
        };
        let b = probes::reflected(&self.b0, e, &self.h, &self.probe_albedo);
        if self.probe_sh.len() != self.probe_decoded.len() {
            self.probe_sh = vec![Default::default(); self.probe_decoded.len()];
        }
        self.probe_decoded.update(
            &b,
            self.sky_cells.as_deref(),
            &emitted,
            which,
            &mut self.probe_sh,
        );
    }

    /// The probes' coefficients after the last frame (empty when the bake
    /// has no probes).
    pub fn probe_sh(&self) -> &[probes::Sh] {
        &self.probe_sh
    }

    /// The sky's mean radiance per cell the probes saw in the last frame
    /// (`None`: no sky).
    pub fn sky_cells(&self) -> Option<&[[f32; 3]]> {
        self.sky_cells.as_deref()
    }

    /// The probe lookup over the last frame's probes (`None` when the bake
    /// has none).
    pub fn probe_lookup(&self) -> Option<probes::Lookup<'_>> {
        (!self.baked.probes.is_empty()).then(|| probes::Lookup {
            grid: self.baked.probes.grid,
            states: &self.baked.probes.states,
            sh: &self.probe_sh,
            scene: &self.direct,
        })
    }

    /// `D` on the patches after the last frame (matrix order).
    pub fn d(&self) -> &[Vec<f32>; 3] {
        &self.d
    }

    /// `B0 = ρ ∘ D + E` of the last frame.
    pub fn b0(&self) -> &[Vec<f32>; 3] {
        &self.b0
    }

    /// `H = T̃ · B0` of the last frame.
    pub fn h(&self) -> &[Vec<f32>; 3] {
        &self.h
    }

    /// One product `T̃ · b0` over `b0`'s active columns (all columns when
    /// column skipping is off).
    pub fn product(&self, b0: &[Vec<f32>; 3]) -> ([Vec<f32>; 3], GatherStats, usize) {
        self.product_over(b0, !self.options.skip_columns)
    }

    /// [`Runtime::product`] over every column, or over `b0`'s active ones
    /// whatever the options say.
    pub fn product_over(
        &self,
        b0: &[Vec<f32>; 3],
        every_column: bool,
    ) -> ([Vec<f32>; 3], GatherStats, usize) {
        let refs = [&b0[0][..], &b0[1][..], &b0[2][..]];
        let tile = self.baked.matrix.index.tile;
        let mut h = std::array::from_fn(|_| vec![0.0; self.n()]);
        if every_column || self.options.cull <= 0.0 {
            let active = ActiveColumns::of(refs, tile, every_column);
            let stats = self.gather.gather(refs, &active, &mut h);
            return (h, stats, active.active_groups);
        }
        let culled = ActiveColumns::culled(refs, tile, self.column_weights(), self.options.cull);
        let mut stats = self.gather.gather(refs, &culled.columns, &mut h);
        stats.culled_groups = culled.culled_groups as u64;
        stats.culled_mass = culled.dropped_mass;
        stats.mass = culled.mass;
        (h, stats, culled.columns.active_groups)
    }

    /// `T̃`'s column sums per channel, the culling's weights (computed at
    /// the first call unless [`Runtime::new`] did).
    pub fn column_weights(&self) -> &[Vec<f64>; 3] {
        self.weights.get_or_init(|| self.baked.matrix.column_sums())
    }

    /// The near-field weights for `m` lit points per patch, as this run
    /// time's options ask (none when the option is off), for another
    /// renderer of the same frame (the GL one).
    pub fn near_field_weights(&self, m: usize) -> NearFieldWeights {
        near_weights(&self.baked, self.options.near_field, m)
    }

    /// `H` of one light's term: `T̃ · b0`, or with the near-field
    /// correction `c` from the exitance at the lit points (`d_points`,
    /// [`direct::irradiance`]), `T̃ · (b0 + ρ ∘ c) + c`.
    pub fn light_product(
        &self,
        b0: &[Vec<f32>; 3],
        d_points: &[Vec<f32>; 3],
    ) -> ([Vec<f32>; 3], GatherStats, usize) {
        self.light_product_over(b0, d_points, !self.options.skip_columns)
    }

    /// [`Runtime::light_product`] over every column, or over the active
    /// ones of its gather's input, whatever the options say: what a frame
    /// computes for one light, near-field correction included.
    pub fn light_product_over(
        &self,
        b0: &[Vec<f32>; 3],
        d_points: &[Vec<f32>; 3],
        every_column: bool,
    ) -> ([Vec<f32>; 3], GatherStats, usize) {
        self.corrected_over(b0, self.near_correction(d_points).as_ref(), every_column)
    }

    /// The near-field correction (`c` and `δ`) of a term whose direct
    /// light at the lit points is `d_points` (`None` when the bake has
    /// none).
    ///
    /// `d_points` holds `m` points per patch; lit with another count than
    /// the run time's weights (the sample-point option changed since the
    /// last frame), the weights of `m` points are made for this call.
    pub fn near_correction(&self, d_points: &[Vec<f32>; 3]) -> Option<NearTerms> {
        if self.near.is_empty() {
            return None;
        }
        let n = self.n().max(1);
        let m = d_points[0].len() / n;
        if m != self.near.m && d_points[0].len() == m * n && (1..=bakefile_samples()).contains(&m) {
            let near = near_weights(&self.baked, true, m);
            return Some(near.correction_reflected(d_points, &self.baked.patches));
        }
        Some(
            self.near
                .correction_reflected(d_points, &self.baked.patches),
        )
    }

    /// `T̃ · b0`, or with a correction, `T̃ · (b0 + δ + ρ ∘ c) + c`.
    pub fn corrected_product(
        &self,
        b0: &[Vec<f32>; 3],
        near: Option<&NearTerms>,
    ) -> ([Vec<f32>; 3], GatherStats, usize) {
        self.corrected_over(b0, near, !self.options.skip_columns)
    }

    fn corrected_over(
        &self,
        b0: &[Vec<f32>; 3],
        near: Option<&NearTerms>,
        every_column: bool,
    ) -> ([Vec<f32>; 3], GatherStats, usize) {
        let Some(near) = near else {
            return self.product_over(b0, every_column);
        };
        let input = near.gather_input(b0, &self.baked.patches);
        let (mut h, g, active) = self.product_over(&input, every_column);
        for (hc, cc) in h.iter_mut().zip(&near.c) {
            for (hv, cv) in hc.iter_mut().zip(cc) {
                *hv += cv;
            }
        }
        (h, g, active)
    }

    /// The sky of the next frames (`None`: black). A bake without sky
    /// visibility cannot be lit by one, nor can an invalid sky or a map not
    /// read ([`sky::check`]): the error says which, and the sky stays as it
    /// was.
    pub fn set_sky(&mut self, sky: Option<radiosity_core::sky::Sky>) -> Result<(), sky::SkyError> {
        if let Some(s) = &sky {
            sky::check(&self.baked, s)?;
        }
        self.sky = sky;
        Ok(())
    }

    /// The sky lighting the frames.
    pub fn sky(&self) -> Option<&radiosity_core::sky::Sky> {
        self.sky.as_ref()
    }

    /// The deviation of `H` in each patch's 16 face cells after the last
    /// frame (three channels, `n × 16`; [`NearFieldWeights::receiver_deviation`]),
    /// which pixels add bilinearly ([`surface::at_cells`]); `None` when the
    /// bake stores no counts by the receiver's cell or the correction is
    /// off.
    pub fn h_points(&self) -> Option<&[Vec<f32>; 3]> {
        self.h_points.as_ref()
    }

    /// `D_sky` on the patches after the last frame (matrix order), when a
    /// sky lit it.
    pub fn d_sky(&self) -> Option<&[Vec<f32>; 3]> {
        self.sky_term.as_ref().map(|(_, t)| &t.d)
    }

    /// Lights the scene with `lights` and the emission `scales` (material
    /// name → scale, unlisted materials 1): `D`, `B0` and `H` (module doc
    /// for what is reused).
    pub fn frame(&mut self, lights: &[Light], scales: &BTreeMap<String, f32>) -> FrameStats {
        let start = Instant::now();
        let n = self.n();
        let groups = n.div_ceil(4);
        let mut stats = FrameStats::default();
        // Terms computed with other options are not reused, and the
        // near-field weights follow the sample points lit (their count
        // indexes the points' irradiance).
        let with = (self.options.cull, self.options.samples);
        let cache = self.options.cache && self.cached_with == with;
        self.cached_with = with;
        let m = self.options.samples.clamp(1, bakefile_samples());
        if self.near.m != m {
            self.near = near_weights(&self.baked, !self.near.is_empty(), m);
        }
        let per_term = lights_per_term(lights.len(), n, self.options.term_cache_bytes);
        let mut changed =
            !cache || self.frames == 0 || self.terms.len() != lights.len().div_ceil(per_term);

        // Emission.
        let emission_ok = cache
            && self
                .emission_term
                .as_ref()
                .is_some_and(|(s, _)| s == scales);
        if emission_ok {
            stats.terms_reused += 1;
        } else {
            changed = true;
            let e = self.emission.exitance(n, scales);
            let t0 = Instant::now();
            let (h, g, active) = self.product(&e);
            stats.seconds_gather += t0.elapsed().as_secs_f64();
            add_gather(&mut stats, &g, active, groups);
            stats.terms_computed += 1;
            self.emission_term = Some((
                scales.clone(),
                Term {
                    lights: Vec::new(),
                    d: std::array::from_fn(|_| vec![0.0; n]),
                    b0: e,
                    h,
                },
            ));
        }

        // The sky: `D_sky` from the baked visibility, `ρ ∘ D_sky` gathered
        // like a light's `B0`; no term without a sky. The near-field
        // correction sees the sky at the lit points shaped by each cell's
        // open sky (`NearFieldWeights::sky_points`); a bake without it
        // gets none for the sky (every point at the patch's `D_sky`, which
        // the correction's weights, summing to 0 over a patch's points,
        // ignore: measured at 1e-9 of `H` on Sponza).
        let sky_ok = cache
            && match (&self.sky, &self.sky_term) {
                (None, None) => true,
                (Some(s), Some((t, _))) => s == t,
                _ => false,
            };
        if sky_ok {
            stats.terms_reused += usize::from(self.sky.is_some());
        } else {
            changed = true;
            self.sky_cells = self.sky.as_ref().map(|s| {
                s.cell_radiance()
                    .into_iter()
                    .map(|c| c.map(|v| v as f32))
                    .collect()
            });
            self.sky_term = match self.sky.clone() {
                None => None,
                Some(s) => {
                    let t0 = Instant::now();
                    let d = sky::irradiance(&self.baked, &s).expect("checked by set_sky");
                    let b0 = direct::reflected(&self.baked, &d);
                    stats.seconds_direct += t0.elapsed().as_secs_f64();
                    let t0 = Instant::now();
                    let c = self
                        .near
                        .sky_points(&d)
                        .and_then(|p| self.near_correction(&p));
                    stats.seconds_near_field += t0.elapsed().as_secs_f64();
                    let t0 = Instant::now();
                    let (h, g, active) = self.corrected_product(&b0, c.as_ref());
                    stats.seconds_gather += t0.elapsed().as_secs_f64();
                    add_gather(&mut stats, &g, active, groups);
                    stats.terms_computed += 1;
                    Some((
                        s,
                        Term {
                            lights: Vec::new(),
                            d,
                            b0,
                            h,
                        },
                    ))
                }
            };
        }

        // Lights.
        self.terms.truncate(lights.len().div_ceil(per_term));
        for (i, group) in lights.chunks(per_term).enumerate() {
            if cache && self.terms.get(i).is_some_and(|t| t.lights == group) {
                stats.terms_reused += 1;
                continue;
            }
            changed = true;
            let t0 = Instant::now();
            let (d_points, d) =
                direct::irradiance(&self.baked, &self.direct, group, self.options.samples);
            stats.seconds_direct += t0.elapsed().as_secs_f64();
            let b0 = direct::reflected(&self.baked, &d);
            let t0 = Instant::now();
            let c = self.near_correction(&d_points);
            stats.seconds_near_field += t0.elapsed().as_secs_f64();
            let t0 = Instant::now();
            let (h, g, active) = self.corrected_product(&b0, c.as_ref());
            stats.seconds_gather += t0.elapsed().as_secs_f64();
            add_gather(&mut stats, &g, active, groups);
            stats.terms_computed += 1;
            let term = Term {
                lights: group.to_vec(),
                d,
                b0,
                h,
            };
            if i < self.terms.len() {
                self.terms[i] = term;
            } else {
                self.terms.push(term);
            }
        }

        self.frames += 1;
        if !changed {
            stats.unchanged = true;
            stats.seconds_total = start.elapsed().as_secs_f64();
            return stats;
        }
        // Sum the terms in a fixed order: emission, the sky, then lights in
        // order.
        let (_, e) = self.emission_term.as_ref().expect("set above");
        for c in 0..3 {
            self.d[c].copy_from_slice(&e.d[c]);
            self.b0[c].copy_from_slice(&e.b0[c]);
            self.h[c].copy_from_slice(&e.h[c]);
            for t in self.sky_term.iter().map(|(_, t)| t).chain(&self.terms) {
                for j in 0..n {
                    self.d[c][j] += t.d[c][j];
                    self.b0[c][j] += t.b0[c][j];
                    self.h[c][j] += t.h[c][j];
                }
            }
        }
        // How `H` spreads over each receiver near its neighbours.
        let t0 = Instant::now();
        self.h_points = self
            .near
            .receiver_deviation(&self.b0, &self.h, &self.baked.patches);
        stats.seconds_near_field += t0.elapsed().as_secs_f64();
        if !self.probe_decoded.is_empty() {
            let t0 = Instant::now();
            let demand = self.probe_demand.take();
            self.update_probes(demand.as_deref());
            self.probe_demand = demand;
            stats.seconds_probes = t0.elapsed().as_secs_f64();
        }
        stats.seconds_total = start.elapsed().as_secs_f64();
        stats
    }
}

/// The near-field weights of `baked` for `m` lit points (none when `on` is
/// false).
/// Sample points per patch a bake stores: the most a frame lights.
fn bakefile_samples() -> usize {
    radiosity_bakefile::surface::SAMPLES_PER_PATCH
}

fn near_weights(baked: &Baked, on: bool, m: usize) -> NearFieldWeights {
    let none = Default::default();
    let nf = if on { &baked.near_field } else { &none };
    NearFieldWeights::new(nf, &baked.samples, baked.patches.len(), m)
}

fn add_gather(stats: &mut FrameStats, g: &GatherStats, active: usize, groups: usize) {
    stats.gather.bytes_read += g.bytes_read;
    stats.gather.tiles_touched += g.tiles_touched;
    stats.gather.tiles_skipped += g.tiles_skipped;
    stats.gather.entries += g.entries;
    stats.gather.sparse_entries += g.sparse_entries;
    stats.gather.culled_groups += g.culled_groups;
    stats.gather.culled_mass += g.culled_mass;
    stats.gather.mass += g.mass;
    stats.active_groups += active;
    stats.total_groups += groups;
}
