//! Bake stage: irradiance probes (issue 46; the layout and the mathematics
//! are `radiosity_bakefile::probes`'). A regular grid over the scene's
//! bounds, centred on them ([`ProbeSpacing`]); from each probe a spherical
//! Fibonacci set of directions (Keinert et al., "Spherical Fibonacci
//! Mapping", 2015: equal areas, low discrepancy) is traced through the
//! scene as the form factors trace theirs ([`crate::form_factor::rays`]).
//! A ray that meets a patch's surface counts towards that patch's entry,
//! one that leaves the scene towards its sky cell's, one that meets an
//! emissive face also towards its material's; each entry keeps the rays'
//! amount and mean direction. A ray that meets the back of a surface
//! counts towards the probe being in a solid.

use crate::error::BakeError;
use crate::form_factor::tracer::{with_tracer, Hit, Tracer};
use crate::voxelize::Voxelization;
use radiosity_bakefile::probes::{
    ProbeEntries, ProbeGrid, ProbeState, Probes, OPEN_FRACTION, SOLID_FRACTION,
};
use radiosity_core::scene::Scene;
use radiosity_core::sky::cells::{cell, CELLS};
use rayon::prelude::*;
use serde::Serialize;

/// The closest the automatic spacing puts probes, in voxels: two voxels
/// leave a probe between facing walls of any room the patches resolve.
pub const MIN_AUTO_SPACING_VOXELS: f64 = 2.0;

/// Patches per probe the automatic spacing aims at: a probe sees a few
/// hundred patches (Sponza: 310, the Cornell box at 4k: 560), so its
/// entries stay a fraction of the bake (Sponza at 4k: 588 probes, 9.5 %
/// of the file) and the update of every probe a fraction of the gather.
pub const PATCHES_PER_PROBE: f64 = 8.0;

/// Default rays per probe: with band 2's truncation, the probes'
/// irradiance is within 1.8 % of 65,536 brute-force rays on the same
/// radiance field (`tests/probes.rs`).
pub const DEFAULT_RAYS: u32 = 1024;

/// Most probes a bake makes.
pub const MAX_PROBES: usize = 65_536;

/// Bytes an entry takes while the bake holds it (the file's 20 and the
/// list's own).
const ENTRY_BYTES: u64 = 24;

/// Most rays per probe.
pub const MAX_RAYS: u32 = 65_536;

/// How far apart the probes are.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum ProbeSpacing {
    /// One probe per [`PATCHES_PER_PROBE`] patches over the scene's
    /// bounding box, at least [`MIN_AUTO_SPACING_VOXELS`] apart.
    Auto,
    /// This many voxels (0: no probes).
    Voxels(f64),
}

/// The probe options of a bake.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ProbeOptions {
    pub spacing: ProbeSpacing,
    /// Rays per probe.
    pub rays: u32,
}

impl Default for ProbeOptions {
    fn default() -> ProbeOptions {
        ProbeOptions {
            spacing: ProbeSpacing::Auto,
            rays: DEFAULT_RAYS,
        }
    }
}

impl ProbeOptions {
    /// Whether the bake makes probes.
    pub fn enabled(&self) -> bool {
        match self.spacing {
            ProbeSpacing::Auto => true,
            ProbeSpacing::Voxels(v) => v > 0.0,
        }
    }

    /// The spacing in scene units for `patches` patches of `voxel` size in
    /// a scene whose bounds are `extent`.
    pub fn spacing_for(&self, voxel: f64, patches: usize, extent: [f64; 3]) -> f64 {
        match self.spacing {
            ProbeSpacing::Voxels(v) => v * voxel,
            ProbeSpacing::Auto => {
                let volume: f64 = extent.iter().map(|e| e.max(voxel)).product();
                let probes = (patches as f64 / PATCHES_PER_PROBE).max(1.0);
                (volume / probes)
                    .cbrt()
                    .max(MIN_AUTO_SPACING_VOXELS * voxel)
            }
        }
    }

    /// Checks the values.
    pub fn validate(&self) -> Result<(), BakeError> {
        if let ProbeSpacing::Voxels(v) = self.spacing {
            if !(v.is_finite() && v >= 0.0) {
                return Err(BakeError::InvalidOption {
                    option: "probe spacing in voxels",
                    value: v.to_string(),
                    expected: "a finite number ≥ 0 (0: no probes), or auto".into(),
                });
            }
        }
        if self.enabled() && !(1..=MAX_RAYS).contains(&self.rays) {
            return Err(BakeError::InvalidOption {
                option: "rays per probe",
                value: self.rays.to_string(),
                expected: format!("1..={MAX_RAYS}"),
            });
        }
        Ok(())
    }
}

/// What the stage made, for the bake report.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ProbeStats {
    pub probes: u64,
    pub dims: [u32; 3],
    pub spacing: f64,
    pub rays: u32,
    /// Probes in the empty space, in solids, under the open sky.
    pub valid: u64,
    pub solid: u64,
    pub open: u64,
    /// Patch and sky entries stored.
    pub entries: u64,
    pub sky_entries: u64,
    pub emission_entries: u64,
    /// The section's bytes.
    pub bytes: u64,
}

/// Direction `k` of the `n`-point spherical Fibonacci set: `y` in equal
/// steps, the azimuth advancing by the golden angle.
pub fn fibonacci_direction(k: usize, n: usize) -> [f64; 3] {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let y = 1.0 - (2.0 * k as f64 + 1.0) / n as f64;
    let r = (1.0 - y * y).max(0.0).sqrt();
    let phi = golden * k as f64;
    [r * phi.cos(), y, r * phi.sin()]
}

/// Where a probe's ray ends.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RayEnd {
    /// On a front face: the patch that owns the point (matrix order before
    /// reordering, as the file's; `None`: a covered point no patch owns),
    /// and the face's material when it emits.
    Surface {
        patch: Option<u32>,
        emitter: Option<u32>,
    },
    /// Out of the scene through sky cell `c`.
    Sky(u8),
    /// On the back of a surface.
    Back,
}

/// The grid over `scene`'s bounds at `spacing`, centred on them; an error
/// beyond [`MAX_PROBES`].
pub fn grid(scene: &Scene, spacing: f64) -> Result<ProbeGrid, BakeError> {
    let (lo, hi) = scene.bounds();
    let mut dims = [0u32; 3];
    let mut origin = [0f32; 3];
    let mut total = 1f64;
    for a in 0..3 {
        let extent = f64::from(hi[a] - lo[a]).max(0.0);
        let d = (extent / spacing).ceil().max(1.0);
        total *= d;
        if total > MAX_PROBES as f64 {
            return Err(BakeError::TooLarge {
                stage: "probes",
                detail: format!(
                    "a spacing of {spacing:.4e} over the scene's extent {:?} makes more than \
                     {MAX_PROBES} probes; a larger spacing fits",
                    (0..3).map(|a| hi[a] - lo[a]).collect::<Vec<_>>()
                ),
            });
        }
        dims[a] = d as u32;
        let centre = 0.5 * (f64::from(lo[a]) + f64::from(hi[a]));
        origin[a] = (centre - 0.5 * spacing * (d - 1.0)) as f32;
    }
    Ok(ProbeGrid {
        dims,
        origin,
        spacing: spacing as f32,
    })
}

/// Where each of `dirs` from each of `points` ends, in `scene` as `vox`
/// cuts it; `patch_index_of` maps the voxelization's patches to the
/// matrix's (`None`: removed). What the stage weighs, and the brute force
/// its tests and benchmark compare with.
pub fn trace(
    scene: &Scene,
    vox: &Voxelization,
    patch_index_of: &[Option<u32>],
    points: &[[f64; 3]],
    dirs: &[[f64; 3]],
) -> Vec<Vec<RayEnd>> {
    with_tracer(scene, vox, |tracer, _, _| {
        trace_with(tracer, scene, patch_index_of, points, dirs)
    })
}

fn trace_with(
    tracer: &Tracer,
    scene: &Scene,
    patch_index_of: &[Option<u32>],
    points: &[[f64; 3]],
    dirs: &[[f64; 3]],
) -> Vec<Vec<RayEnd>> {
    let emitter = |tri: u32| {
        let m = scene.triangle_material[tri as usize];
        scene.materials[m as usize]
            .emission
            .iter()
            .any(|&e| e > 0.0)
            .then_some(m)
    };
    points
        .par_iter()
        .map(|&x| {
            dirs.iter()
                .map(|&d| match tracer.trace(x, d, d) {
                    Hit::Owned { patch, tri, .. } => RayEnd::Surface {
                        patch: patch_index_of[patch as usize],
                        emitter: emitter(tri),
                    },
                    Hit::Unowned { tri } => RayEnd::Surface {
                        patch: None,
                        emitter: emitter(tri),
                    },
                    Hit::Escaped => RayEnd::Sky(cell(d) as u8),
                    Hit::Back => RayEnd::Back,
                })
                .collect()
        })
        .collect()
}

/// One probe's state and entries from where its `ends` (along the
/// Fibonacci set of their count) ended: per patch and sky cell met, the
/// amount `a` and the rays' mean direction `m`
/// (`radiosity_bakefile::probes`, "Stored as amount and mean direction").
pub fn weigh(ends: &[RayEnd]) -> ProbeEntries {
    let n = ends.len();
    // Per target: rays and the sum of their directions.
    type Acc = (u32, [f64; 3]);
    let mut patches: std::collections::BTreeMap<u32, Acc> = Default::default();
    let mut emitters: std::collections::BTreeMap<u32, Acc> = Default::default();
    let mut sky = vec![(0u32, [0.0f64; 3]); CELLS];
    let (mut back, mut out) = (0usize, 0usize);
    let add = |acc: &mut Acc, d: [f64; 3]| {
        acc.0 += 1;
        for (s, x) in acc.1.iter_mut().zip(d) {
            *s += x;
        }
    };
    for (k, e) in ends.iter().enumerate() {
        let d = fibonacci_direction(k, n);
        match *e {
            RayEnd::Surface { patch, emitter } => {
                if let Some(j) = patch {
                    add(patches.entry(j).or_insert((0, [0.0; 3])), d);
                }
                if let Some(m) = emitter {
                    add(emitters.entry(m).or_insert((0, [0.0; 3])), d);
                }
            }
            RayEnd::Sky(c) => {
                out += 1;
                add(&mut sky[usize::from(c)], d);
            }
            RayEnd::Back => back += 1,
        }
    }
    if back as f64 > SOLID_FRACTION * n as f64 {
        return ProbeEntries {
            state: Some(ProbeState::Solid),
            ..ProbeEntries::default()
        };
    }
    let entry = |(k, sum): (u32, [f64; 3]), per_ray: f64| -> [f32; 4] {
        let m = sum.map(|x| x / f64::from(k));
        // Rounding can leave |m| a hair above 1 for a single ray's
        // direction: scale it back.
        let len = radiosity_core::math::norm(m);
        let m = if len > 1.0 { m.map(|x| x / len) } else { m };
        [
            (per_ray * f64::from(k)) as f32,
            m[0] as f32,
            m[1] as f32,
            m[2] as f32,
        ]
    };
    let pi = std::f64::consts::PI;
    ProbeEntries {
        state: Some(if out as f64 > OPEN_FRACTION * n as f64 {
            ProbeState::Open
        } else {
            ProbeState::Valid
        }),
        patches: patches
            .into_iter()
            .map(|(j, acc)| (j, entry(acc, 4.0 / n as f64)))
            .collect(),
        sky: sky
            .into_iter()
            .enumerate()
            .filter(|(_, acc)| acc.0 > 0)
            .map(|(c, acc)| (c as u8, entry(acc, 4.0 * pi / n as f64)))
            .collect(),
        emission: emitters
            .into_iter()
            .map(|(m, acc)| (m, entry(acc, 4.0 / n as f64)))
            .collect(),
    }
}

/// The stage: the grid at `options`' spacing, each probe traced and
/// weighed. Probes are traced in chunks so that the ray ends held at once
/// stay a few MB.
pub fn build(
    scene: &Scene,
    vox: &Voxelization,
    patch_index_of: &[Option<u32>],
    options: &ProbeOptions,
) -> Result<(Probes, ProbeStats), BakeError> {
    options.validate()?;
    if !options.enabled() {
        return Ok((Probes::none(), ProbeStats::default()));
    }
    let (lo, hi) = scene.bounds();
    let patches = patch_index_of.iter().filter(|p| p.is_some()).count();
    let spacing = options.spacing_for(
        vox.grid.size,
        patches,
        std::array::from_fn(|a| f64::from(hi[a] - lo[a])),
    );
    let g = grid(scene, spacing)?;
    let rays = options.rays as usize;
    // The most entries the probes can hold (a ray adds at most one entry
    // to its patch, and one to its material), against the memory there is.
    let most = g.len() as u64 * 2 * (rays as u64).min((patches + CELLS) as u64) * ENTRY_BYTES;
    if let Some(free) = crate::budget::host_available() {
        if most > free / 2 {
            return Err(BakeError::TooLarge {
                stage: "probes",
                detail: format!(
                    "{} probes of {rays} rays could hold {most} bytes of entries, more than half \
                     the {free} bytes available; a larger probe spacing or fewer rays per probe \
                     fits",
                    g.len()
                ),
            });
        }
    }
    let dirs: Vec<[f64; 3]> = (0..rays).map(|k| fibonacci_direction(k, rays)).collect();
    let points: Vec<[f64; 3]> = (0..g.len()).map(|p| g.position(p)).collect();
    let chunk = (4 << 20) / rays.max(1);
    let entries = with_tracer(scene, vox, |tracer, _, _| {
        let mut entries = Vec::with_capacity(points.len());
        for part in points.chunks(chunk.max(1)) {
            let ends = trace_with(tracer, scene, patch_index_of, part, &dirs);
            entries.extend(ends.par_iter().map(|e| weigh(e)).collect::<Vec<_>>());
        }
        entries
    });
    let probes = Probes::from_entries(options.rays, g, &entries);
    let count = |s: ProbeState| probes.states.iter().filter(|&&x| x == s).count() as u64;
    let stats = ProbeStats {
        probes: g.len() as u64,
        dims: g.dims,
        spacing,
        rays: options.rays,
        valid: count(ProbeState::Valid),
        solid: count(ProbeState::Solid),
        open: count(ProbeState::Open),
        entries: probes.patches.len() as u64,
        sky_entries: probes.sky_cells.len() as u64,
        emission_entries: probes.emitters.len() as u64,
        bytes: probes.to_bytes().len() as u64,
    };
    Ok((probes, stats))
}
