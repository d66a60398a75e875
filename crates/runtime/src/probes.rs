//! Irradiance probes at run time (issue 46), the CPU reference of
//! `crates/gl/glsl/probes.comp` and of the probe lookup in
//! `crates/gl/glsl/object.frag`. Each frame whose light changed, every
//! used probe's band-2 radiance coefficients are summed from the patches'
//! reflected exitance `B − E = B0 − E + ρ∘H`, the emissive materials'
//! exitance (`scale × Ke`) and the sky's cell radiances through the baked
//! entries (`radiosity_bakefile::probes`, whose [`weights`] decodes an
//! entry); a point of a moving object then takes the irradiance about its
//! normal from the probes around it.
//!
//! **The lookup** ([`Lookup::irradiance`]): the eight probes of the grid
//! cell holding the point, weighted trilinearly, each times
//!  - 0 when the probe is in a solid (`ProbeState::Solid`),
//!  - 0 when the segment from the point (lifted along its normal) to the
//!    probe crosses the scene: a probe behind a wall gives nothing, so no
//!    light leaks through it (Majercik et al., "Dynamic Diffuse Global
//!    Illumination with Ray-Traced Irradiance Fields", JCGT 2019, use depth
//!    moments for this; a shadow ray against the scene's BVH is exact),
//!  - and DDGI's smooth backface weight `((1 + n·ω)/2)² + 0.2`, `ω` towards
//!    the probe, which favours the probes in front of the surface.
//!
//! When all eight are hidden the point gets no indirect light: it is
//! sealed off from every probe around it (inside the scene's solids, or in
//! a gap narrower than the probe spacing; a finer `--probe-spacing` resolves
//! such gaps).

use radiosity_bakefile::probes::{weights, ProbeGrid, ProbeState, Probes};
use radiosity_core::direct::DirectLight;
use radiosity_core::sh::COEFFICIENTS;
use rayon::prelude::*;

/// One probe's radiance coefficients: 9 × RGB.
pub type Sh = [[f32; 3]; COEFFICIENTS];

/// The clamped-cosine kernel's band factors `Â_l` (Ramamoorthi and Hanrahan
/// 2001): π, 2π/3, π/4.
pub const A_HAT: [f32; 3] = [
    std::f32::consts::PI,
    2.0 * std::f32::consts::PI / 3.0,
    std::f32::consts::PI / 4.0,
];

/// The band of coefficient `l`.
const BAND: [usize; COEFFICIENTS] = [0, 1, 1, 1, 2, 2, 2, 2, 2];

/// The probes' entries decoded once for the frames: per entry its patch
/// (or sky cell) and its nine weights in f32 ([`weights`]), so that an
/// update is 27 multiply-adds an entry.
#[derive(Clone, Debug, Default)]
pub struct Decoded {
    pub starts: Vec<u32>,
    pub patches: Vec<u32>,
    pub weights: Vec<[f32; COEFFICIENTS]>,
    pub sky_starts: Vec<u32>,
    pub sky_cells: Vec<u32>,
    pub sky_weights: Vec<[f32; COEFFICIENTS]>,
    pub emission_starts: Vec<u32>,
    pub emitters: Vec<u32>,
    pub emission_weights: Vec<[f32; COEFFICIENTS]>,
    pub states: Vec<ProbeState>,
}

impl Decoded {
    /// `probes` decoded.
    pub fn new(probes: &Probes) -> Decoded {
        Decoded {
            starts: probes.starts.clone(),
            patches: probes.patches.clone(),
            weights: probes.entries.iter().map(|&e| weights(e)).collect(),
            sky_starts: probes.sky_starts.clone(),
            sky_cells: probes.sky_cells.iter().map(|&c| u32::from(c)).collect(),
            sky_weights: probes.sky_entries.iter().map(|&e| weights(e)).collect(),
            emission_starts: probes.emission_starts.clone(),
            emitters: probes.emitters.clone(),
            emission_weights: probes
                .emission_entries
                .iter()
                .map(|&e| weights(e))
                .collect(),
            states: probes.states.clone(),
        }
    }

    /// Probes.
    pub fn len(&self) -> usize {
        self.states.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.states.is_empty()
    }

    /// Probe `p`'s coefficients from the patches' reflected exitance `b`
    /// (interleaved RGB, matrix order), the sky's mean radiance per cell
    /// (`None`: black) and the materials' emitted exitance (by material
    /// index; materials beyond it emit nothing); a solid probe's are zero.
    pub fn probe(
        &self,
        p: usize,
        b: &[[f32; 3]],
        sky: Option<&[[f32; 3]]>,
        emitted: &[[f32; 3]],
    ) -> Sh {
        let mut sh = [[0.0f32; 3]; COEFFICIENTS];
        if self.states[p] == ProbeState::Solid {
            return sh;
        }
        let (a, e) = (self.starts[p] as usize, self.starts[p + 1] as usize);
        accumulate(&mut sh, &self.patches[a..e], &self.weights[a..e], b);
        if let Some(sky) = sky {
            let (a, e) = (self.sky_starts[p] as usize, self.sky_starts[p + 1] as usize);
            accumulate(&mut sh, &self.sky_cells[a..e], &self.sky_weights[a..e], sky);
        }
        let (a, e) = (
            self.emission_starts[p] as usize,
            self.emission_starts[p + 1] as usize,
        );
        for k in a..e {
            let m = self.emitters[k] as usize;
            if let Some(v) = emitted.get(m) {
                accumulate(
                    &mut sh,
                    &[0],
                    &self.emission_weights[k..k + 1],
                    std::slice::from_ref(v),
                );
            }
        }
        sh
    }

    /// The coefficients of the probes `which` (all when `None`), in
    /// parallel, written into `out` (one per probe).
    pub fn update(
        &self,
        b: &[[f32; 3]],
        sky: Option<&[[f32; 3]]>,
        emitted: &[[f32; 3]],
        which: Option<&[usize]>,
        out: &mut [Sh],
    ) {
        match which {
            None => out
                .par_iter_mut()
                .enumerate()
                .for_each(|(p, o)| *o = self.probe(p, b, sky, emitted)),
            // A few probes (one object's): on this thread, as waking the
            // pool costs more than they do.
            Some(w) if w.len() <= 64 => {
                for &p in w {
                    out[p] = self.probe(p, b, sky, emitted);
                }
            }
            Some(w) => {
                let got: Vec<(usize, Sh)> = w
                    .par_iter()
                    .map(|&p| (p, self.probe(p, b, sky, emitted)))
                    .collect();
                for (p, sh) in got {
                    out[p] = sh;
                }
            }
        }
    }
}

/// `sh += Σ_k w_k v[idx_k]`: with AVX2 and FMA (detected at run time)
/// eight coefficients in one register per channel, two entries at a time
/// so that the multiply-adds do not wait on each other; else the portable
/// loop. The two sum in different orders: equal to f32 rounding.
fn accumulate(sh: &mut Sh, idx: &[u32], w: &[[f32; COEFFICIENTS]], v: &[[f32; 3]]) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the features are present.
            unsafe { accumulate_avx2(sh, idx, w, v) };
            return;
        }
    }
    accumulate_portable(sh, idx, w, v);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn accumulate_avx2(sh: &mut Sh, idx: &[u32], w: &[[f32; COEFFICIENTS]], v: &[[f32; 3]]) {
    use std::arch::x86_64::*;
    // Two sets of accumulators in named variables (registers), one per
    // entry of a pair.
    let (mut r0, mut g0, mut b0) = (
        _mm256_setzero_ps(),
        _mm256_setzero_ps(),
        _mm256_setzero_ps(),
    );
    let (mut r1, mut g1, mut b1) = (
        _mm256_setzero_ps(),
        _mm256_setzero_ps(),
        _mm256_setzero_ps(),
    );
    let mut last = [0.0f32; 3];
    let mut pairs_i = idx.chunks_exact(2);
    let mut pairs_w = w.chunks_exact(2);
    for (i, ww) in (&mut pairs_i).zip(&mut pairs_w) {
        let (x0, x1) = (v[i[0] as usize], v[i[1] as usize]);
        // SAFETY: each weight row holds nine floats; the loads read the
        // first eight.
        let (w0, w1) = unsafe {
            (
                _mm256_loadu_ps(ww[0].as_ptr()),
                _mm256_loadu_ps(ww[1].as_ptr()),
            )
        };
        r0 = _mm256_fmadd_ps(w0, _mm256_set1_ps(x0[0]), r0);
        g0 = _mm256_fmadd_ps(w0, _mm256_set1_ps(x0[1]), g0);
        b0 = _mm256_fmadd_ps(w0, _mm256_set1_ps(x0[2]), b0);
        r1 = _mm256_fmadd_ps(w1, _mm256_set1_ps(x1[0]), r1);
        g1 = _mm256_fmadd_ps(w1, _mm256_set1_ps(x1[1]), g1);
        b1 = _mm256_fmadd_ps(w1, _mm256_set1_ps(x1[2]), b1);
        for c in 0..3 {
            last[c] += ww[0][8] * x0[c] + ww[1][8] * x1[c];
        }
    }
    let mut lanes = [[0.0f32; 8]; 3];
    for (c, t) in [
        _mm256_add_ps(r0, r1),
        _mm256_add_ps(g0, g1),
        _mm256_add_ps(b0, b1),
    ]
    .into_iter()
    .enumerate()
    {
        // SAFETY: eight floats written into an array of eight.
        unsafe { _mm256_storeu_ps(lanes[c].as_mut_ptr(), t) };
    }
    for l in 0..8 {
        for c in 0..3 {
            sh[l][c] += lanes[c][l];
        }
    }
    for c in 0..3 {
        sh[8][c] += last[c];
    }
    accumulate_portable(sh, pairs_i.remainder(), pairs_w.remainder(), v);
}

/// The portable loop of [`accumulate`]: the channels of a coefficient
/// side by side.
fn accumulate_portable(sh: &mut Sh, idx: &[u32], w: &[[f32; COEFFICIENTS]], v: &[[f32; 3]]) {
    let mut acc = [[0.0f32; COEFFICIENTS]; 3];
    for (&j, w) in idx.iter().zip(w) {
        let x = v[j as usize];
        for c in 0..3 {
            for l in 0..COEFFICIENTS {
                acc[c][l] += w[l] * x[c];
            }
        }
    }
    for l in 0..COEFFICIENTS {
        for c in 0..3 {
            sh[l][c] += acc[c][l];
        }
    }
}

/// Every probe's coefficients straight from the file's entries (the
/// reference of [`Decoded::update`], decoding each entry as it goes).
pub fn update(
    probes: &Probes,
    b: &[Vec<f32>; 3],
    sky: Option<&[[f32; 3]]>,
    emitted: &[[f32; 3]],
) -> Vec<Sh> {
    (0..probes.len())
        .into_par_iter()
        .map(|p| probe(probes, p, b, sky, emitted))
        .collect()
}

/// Probe `p`'s coefficients ([`update`]'s).
pub fn probe(
    probes: &Probes,
    p: usize,
    b: &[Vec<f32>; 3],
    sky: Option<&[[f32; 3]]>,
    emitted: &[[f32; 3]],
) -> Sh {
    let mut sh = [[0.0f32; 3]; COEFFICIENTS];
    if probes.states[p] == ProbeState::Solid {
        return sh;
    }
    let mut add = |e: [f32; 4], v: [f32; 3]| {
        let w = weights(e);
        for (s, w) in sh.iter_mut().zip(w) {
            for c in 0..3 {
                s[c] += w * v[c];
            }
        }
    };
    for (j, e) in probes.patch_entries(p) {
        add(e, [b[0][j], b[1][j], b[2][j]]);
    }
    if let Some(sky) = sky {
        for (c, e) in probes.sky_entries_of(p) {
            add(e, sky[c]);
        }
    }
    for (m, e) in probes.emission_entries_of(p) {
        if let Some(&v) = emitted.get(m) {
            add(e, v);
        }
    }
    sh
}

/// The basis at `n` in f32 ([`radiosity_core::sh::basis`]'s order and
/// constants).
pub fn basis(n: [f32; 3]) -> [f32; COEFFICIENTS] {
    radiosity_core::sh::basis(n.map(f64::from)).map(|x| x as f32)
}

/// The irradiance `E(n) = Σ Â_l L_lm Y_lm(n)` of coefficients `sh` about
/// the unit normal `n`, clamped at 0 (band 2 can ring below it where the
/// light is one-sided).
pub fn irradiance(sh: &Sh, n: [f32; 3]) -> [f32; 3] {
    let y = basis(n);
    let mut e = [0.0f32; 3];
    for l in 0..COEFFICIENTS {
        for c in 0..3 {
            e[c] += A_HAT[BAND[l]] * sh[l][c] * y[l];
        }
    }
    e.map(|x| x.max(0.0))
}

/// The patches' reflected exitance `B0 − E + ρ∘H` from a frame's `B0`,
/// its emission `E` (`None`: none), `H` and the patches' albedos,
/// interleaved RGB per patch: what the probes' patch entries carry (the
/// emission comes through their emission entries).
pub fn reflected(
    b0: &[Vec<f32>; 3],
    e: Option<&[Vec<f32>; 3]>,
    h: &[Vec<f32>; 3],
    albedo: &[[f32; 3]],
) -> Vec<[f32; 3]> {
    albedo
        .iter()
        .enumerate()
        .map(|(j, a)| {
            std::array::from_fn(|c| b0[c][j] - e.map_or(0.0, |e| e[c][j]) + a[c] * h[c][j])
        })
        .collect()
}

/// Each material's emitted exitance under the emission `scales` (by
/// name; 1 when absent): `scale × Ke`.
pub fn emitted(
    materials: &[radiosity_core::scene::Material],
    scales: &std::collections::BTreeMap<String, f32>,
) -> Vec<[f32; 3]> {
    materials
        .iter()
        .map(|m| {
            let s = scales.get(&m.name).copied().unwrap_or(1.0);
            m.emission.map(|k| s * k)
        })
        .collect()
}

/// The probe lookup at points of moving objects (module doc).
pub struct Lookup<'a> {
    pub grid: ProbeGrid,
    pub states: &'a [ProbeState],
    pub sh: &'a [Sh],
    /// The scene's shadow rays (the static scene only: a moving object
    /// does not hide a probe from itself).
    pub scene: &'a DirectLight,
}

/// The probes a lookup anywhere in the box `[lo, hi]` may read: the
/// corners of the grid cells it overlaps, in increasing order.
pub fn needed(grid: &ProbeGrid, lo: [f64; 3], hi: [f64; 3]) -> Vec<usize> {
    let mut range = [(0u32, 0u32); 3];
    for a in 0..3 {
        let cell = |x: f64| {
            ((x - f64::from(grid.origin[a])) / f64::from(grid.spacing))
                .floor()
                .clamp(0.0, f64::from(grid.dims[a].saturating_sub(1)))
        };
        let last = grid.dims[a].saturating_sub(1);
        let l = (cell(lo[a]) as u32).min(last.saturating_sub(1));
        let h = (cell(hi[a]) as u32 + 1).min(last);
        range[a] = (l, h);
    }
    let mut out = Vec::new();
    for k in range[2].0..=range[2].1 {
        for j in range[1].0..=range[1].1 {
            for i in range[0].0..=range[0].1 {
                out.push(grid.index([i, j, k]));
            }
        }
    }
    out
}

impl Lookup<'_> {
    /// The grid cell (its lowest corner) holding `x`, and `x`'s fraction
    /// within it, clamped to the grid.
    pub fn cell(&self, x: [f64; 3]) -> ([u32; 3], [f64; 3]) {
        let g = &self.grid;
        let mut base = [0u32; 3];
        let mut t = [0.0; 3];
        for a in 0..3 {
            let u = (x[a] - f64::from(g.origin[a])) / f64::from(g.spacing);
            let last = g.dims[a].saturating_sub(2) as f64;
            let b = u.floor().clamp(0.0, last);
            base[a] = b as u32;
            t[a] = if g.dims[a] < 2 {
                0.0
            } else {
                (u - b).clamp(0.0, 1.0)
            };
        }
        (base, t)
    }

    /// How probe `p` is seen from `x` (lifted) with normal `n`: 0 hidden
    /// or solid, else the backface weight.
    fn seen(&self, p: usize, x: [f64; 3], n: [f64; 3]) -> f64 {
        if !self.states[p].is_used() {
            return 0.0;
        }
        let q = self.grid.position(p);
        if !self.scene.visible(x, q) {
            return 0.0;
        }
        let d = [q[0] - x[0], q[1] - x[1], q[2] - x[2]];
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let cos = if len > 0.0 {
            (d[0] * n[0] + d[1] * n[1] + d[2] * n[2]) / len
        } else {
            1.0
        };
        let h = 0.5 * (1.0 + cos);
        h * h + 0.2
    }

    /// The probes' irradiance at `x` about the unit normal `n` (module
    /// doc), and the weights used (probe, weight; normalised).
    pub fn irradiance(&self, x: [f64; 3], n: [f64; 3]) -> ([f32; 3], Vec<(usize, f64)>) {
        let g = &self.grid;
        // Lift off the surface as the shadow rays do, so that the point's
        // own (static) surface does not hide the probes in front of it.
        let lift = self.scene.offset();
        let xl = [x[0] + lift * n[0], x[1] + lift * n[1], x[2] + lift * n[2]];
        let (base, t) = self.cell(x);
        let mut used = Vec::with_capacity(8);
        for corner in 0..8u32 {
            let mut c = base;
            let mut w = 1.0;
            for a in 0..3 {
                let hi = (corner >> a) & 1;
                if g.dims[a] < 2 && hi == 1 {
                    w = 0.0;
                }
                c[a] = (base[a] + hi).min(g.dims[a] - 1);
                w *= if hi == 1 { t[a] } else { 1.0 - t[a] };
            }
            if w <= 0.0 {
                continue;
            }
            let p = g.index(c);
            let s = self.seen(p, xl, n);
            if s > 0.0 {
                used.push((p, w * s));
            }
        }
        let total: f64 = used.iter().map(|u| u.1).sum();
        let mut e = [0.0f32; 3];
        if total > 0.0 {
            let nf = n.map(|v| v as f32);
            for u in used.iter_mut() {
                u.1 /= total;
                let ep = irradiance(&self.sh[u.0], nf);
                for c in 0..3 {
                    e[c] += u.1 as f32 * ep[c];
                }
            }
        }
        (e, used)
    }
}
