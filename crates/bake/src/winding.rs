//! Winding, face by face: users' models mix faces wound towards the viewer
//! with faces wound away (an arch's underside, a mirrored chair) and
//! single-sided surfaces seen from both sides (a seat, a partition wall,
//! a billboard). Such a face's back looks at the room, so the room sees
//! it black, and it gets no patch on that side. Whole-scene checks
//! (`bake::facing`) catch a scene wound wholly the wrong way, not a few
//! thousand faces of it: a cathedral had 3,905 black pixels under its
//! arches and baked without a warning.
//!
//! So before voxelizing, every triangle is probed from behind: from a point
//! at its centroid lifted [`LIFT`] scene diagonals off its back, a fan of
//! [`PROBE_RAYS`] rays (the cover test's fan, `cover::fan_direction`)
//! records what each ray meets first. When at least [`SHARE`] of them meet
//! the *front* of another surface in open space, the face is seen from
//! behind and gets a back side there, a reversed coincident copy (what
//! `--two-sided` adds everywhere); a face wound the wrong way then has its
//! patch on the twin, its original looks into the solid and is dropped as
//! covered. "In open space" means:
//! - farther than [`GAP`] times the triangle's size (`√(2A)`): a rug on a
//!   floor or a panel under a ceiling, whose back a thin gap hides, are
//!   left alone;
//! - not itself enclosed: from the point met, not every ray of the same
//!   fan around its normal meets a back (the floor inside a box without a
//!   bottom);
//! - the space is the scene's, not a cavity: either the face's front side
//!   looks into a solid or at nothing (all its fan's rays meet backs or
//!   escape: the face is wound the wrong way, an arch's underside), or one
//!   of the points met behind sees one of the points halfway or nine
//!   tenths along the front side's rays (a partition's far side sees over it, the floor
//!   under a seat sees past it). A cavity that other objects' fronts close
//!   (a cushion open at its back against a sofa's back, a chair leg open at
//!   both ends between the floor and the seat) sees nothing in front: the
//!   generated interior, built of such boxes, got 1,770 back sides with
//!   only the first two conditions;
//! - a back face is a back even where a front face coincides with it: two
//!   boxes touching face to face (a cushion on a sofa) give such pairs,
//!   and counting them as fronts (as the rays form factors do for
//!   two-sided panels, which rays never meet from inside a solid) opened
//!   every enclosure; a two-sided panel behind a face may so go unseen,
//!   which errs towards no back side.
//!
//! Emitting faces get no back side (a light panel emits from its front
//! only, as in every renderer), nor faces that already have a coincident
//! reversed face. The list is recorded in the bake file and the run time
//! rebuilds the baked scene with `Scene::with_back_sides_of`; the bake
//! summary and `info` say how many faces, how much area and which
//! materials. `--two-sided` skips the check. Measured (2026-12-04, 2
//! cores): Sponza 755 faces (0.04 % of the area, most of it the capitals'
//! material `sp_svod_kapitel`) in 0.53 s; the generated interior 20 faces
//! (0.03 %: shelf tops under books without bottoms, which look into the
//! books) in 0.43 s; the bundled Cornell box and the generated stress
//! scenes none (tested).

use crate::cover::fan_direction;
use radiosity_core::bvh::Bvh;
use radiosity_core::math::{dot, norm};
use radiosity_core::scene::Scene;
use rayon::prelude::*;
use serde::Serialize;

/// Lift of the probes' origins off the triangle, in scene diagonals (30
/// times the f32 rounding of coordinates relative to the scene's centre).
pub const LIFT: f64 = 1e-6;

/// Rays per side (the enclosure test's fan: the normal and a ring at 60°).
pub const PROBE_RAYS: usize = crate::cover::ENCLOSED_RAYS;

/// Share of a side's rays that decides (module doc).
pub const SHARE: f64 = 0.5;

/// Fronts nearer than this many triangle sizes (`√(2A)`) behind a face do
/// not count for twinning: a thin gap hides the back (module doc).
pub const GAP: f64 = 0.05;

/// What the winding check found.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Winding {
    /// Triangles given a back side, ascending.
    pub twinned: Vec<u32>,
    /// Their area and the scene's (scene units²).
    pub twinned_area: f64,
    pub scene_area: f64,
    /// The materials with the most twinned area, most first
    /// (at most five), with that area.
    pub materials: Vec<(String, f64)>,
    pub seconds: f64,
    /// Of `twinned`, the triangles of double-sided materials (glTF's
    /// `doubleSided`), which get a back side whatever the probes find;
    /// `twinned_area` and `materials` count only the others.
    pub double_sided: usize,
}

impl Winding {
    /// Whether anything was changed.
    pub fn is_empty(&self) -> bool {
        self.twinned.is_empty()
    }
}

impl std::fmt::Display for Winding {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let share = |a: f64| 100.0 * a / self.scene_area.max(f64::MIN_POSITIVE);
        write!(
            f,
            "winding: {} faces seen from behind ({:.2} % of the area) get a back side",
            self.twinned.len() - self.double_sided,
            share(self.twinned_area)
        )?;
        if self.double_sided > 0 {
            write!(
                f,
                ", and {} faces of double-sided materials",
                self.double_sided
            )?;
        }
        if !self.materials.is_empty() {
            let names: Vec<String> = self
                .materials
                .iter()
                .map(|(m, a)| format!("`{m}` {a:.3e}"))
                .collect();
            write!(f, "; materials {}", names.join(", "))?;
        }
        Ok(())
    }
}

/// What a probe ray meets first.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Met {
    Front,
    Back,
    Nothing,
}

/// The check (module doc).
pub fn check(scene: &Scene) -> Winding {
    let start = std::time::Instant::now();
    let n = scene.triangles.len();
    let (lo, hi) = scene.bounds();
    let diagonal = (0..3)
        .map(|q| (hi[q] - lo[q]) as f64)
        .map(|e| e * e)
        .sum::<f64>()
        .sqrt()
        .max(f64::MIN_POSITIVE);
    let shift: [f64; 3] = std::array::from_fn(|q| 0.5 * (lo[q] as f64 + hi[q] as f64));
    let bvh = Bvh::build(&scene.positions, &scene.triangles, shift);
    let normals = scene.triangle_normals();
    let lift = LIFT * diagonal;
    let reach = 2.0 * diagonal;
    // What the ray from `o` (shifted) along unit `d` meets first, where,
    // and which triangle.
    let first = |o: [f64; 3], d: [f64; 3], own: usize| -> (Met, f64, usize) {
        let Some((leaf, t)) = bvh.closest_hit(o, d.map(|v| v * reach)) else {
            return (Met::Nothing, f64::INFINITY, own);
        };
        let hit = bvh.order[leaf as usize] as usize;
        let dist = t * reach;
        if hit == own {
            // A grazing start on the own plane: nothing decided.
            return (Met::Nothing, dist, own);
        }
        if dot(normals[hit], d) < 0.0 {
            (Met::Front, dist, hit)
        } else {
            (Met::Back, dist, hit)
        }
    };
    // Whether the point `y` (shifted) on triangle `tri` is enclosed: from
    // just in front of it, every ray of the fan around its normal meets a
    // back first (as the cover test's enclosure).
    let enclosed = |y: [f64; 3], tri: usize| -> bool {
        let nh = normals[tri];
        let o: [f64; 3] = std::array::from_fn(|q| y[q] + lift * nh[q]);
        (0..PROBE_RAYS).all(|k| first(o, fan_direction(nh, k, PROBE_RAYS), tri).0 == Met::Back)
    };
    let emissive: Vec<bool> = scene
        .materials
        .iter()
        .map(|m| m.emission.iter().any(|&e| e > 0.0))
        .collect();
    let twinned: Vec<bool> = (0..n)
        .into_par_iter()
        .map(|t| {
            let nrm = normals[t];
            let area = scene.triangle_area(t);
            let m = scene.triangle_material[t] as usize;
            if !(area > 0.0)
                || !nrm.iter().all(|c| c.is_finite())
                || norm(nrm) < 0.5
                || emissive.get(m).copied().unwrap_or(false)
            {
                return false;
            }
            let [a, b, cc] = scene.corners(t);
            let c: [f64; 3] = std::array::from_fn(|q| (a[q] + b[q] + cc[q]) / 3.0);
            let side = |s: f64| -> [f64; 3] {
                std::array::from_fn(|q| c[q] + s * lift * nrm[q] - shift[q])
            };
            let (of, ob) = (side(1.0), side(-1.0));
            let back_n = nrm.map(|v| -v);
            let gap = GAP * (2.0 * area).sqrt();
            let need = (SHARE * PROBE_RAYS as f64).ceil() as usize;
            // Fronts in open space behind the face (module doc), counted
            // until there are enough or too few rays are left.
            let mut open_fronts = 0;
            // The points met, lifted off their surfaces.
            let mut behind: Vec<[f64; 3]> = Vec::new();
            for k in 0..PROBE_RAYS {
                if open_fronts + (PROBE_RAYS - k) < need {
                    break;
                }
                let d = fan_direction(back_n, k, PROBE_RAYS);
                let (met, dist, hit) = first(ob, d, t);
                let y: [f64; 3] = std::array::from_fn(|q| ob[q] + dist * d[q]);
                if met == Met::Front && dist > gap && !enclosed(y, hit) {
                    open_fronts += 1;
                    behind.push(std::array::from_fn(|q| y[q] + lift * normals[hit][q]));
                }
            }
            if open_fronts < need {
                return false;
            }
            // The space behind must be the scene's, not a cavity closed by
            // other objects' fronts (module doc): the front side looks into
            // a solid or at nothing (the face is wound the wrong way), or
            // a point met behind sees a point in front.
            let ahead: Vec<(Met, f64, [f64; 3])> = (0..PROBE_RAYS)
                .map(|k| {
                    let d = fan_direction(nrm, k, PROBE_RAYS);
                    let (met, dist, _) = first(of, d, t);
                    (met, dist, d)
                })
                .collect();
            let closed = ahead.iter().all(|a| a.0 != Met::Front);
            if !closed {
                let targets: Vec<[f64; 3]> = ahead
                    .iter()
                    .flat_map(|&(_, dist, d)| {
                        [0.5, 0.9].map(|f| {
                            let h = f * dist.min(reach);
                            std::array::from_fn(|q| of[q] + h * d[q])
                        })
                    })
                    .collect();
                let seen = behind.iter().any(|&y| {
                    targets.iter().any(|&x| {
                        let d: [f64; 3] = std::array::from_fn(|q| x[q] - y[q]);
                        bvh.any_hit(y, d, |_, _| false).is_none()
                    })
                });
                if !seen {
                    return false;
                }
            }
            // A coincident reversed face already makes it two-sided.
            let across: [f64; 3] = std::array::from_fn(|q| ob[q] - of[q]);
            bvh.any_hit(of, across, |k, _| {
                let hit = bvh.order[k as usize] as usize;
                hit == t || dot(normals[hit], nrm) > -0.5
            })
            .is_none()
        })
        .collect();
    let mut w = Winding {
        scene_area: scene.surface_area(),
        ..Winding::default()
    };
    let mut by_material = vec![0.0f64; scene.materials.len()];
    for t in (0..n).filter(|&t| twinned[t]) {
        let a = scene.triangle_area(t);
        w.twinned.push(t as u32);
        w.twinned_area += a;
        if let Some(m) = by_material.get_mut(scene.triangle_material[t] as usize) {
            *m += a;
        }
    }
    let mut order: Vec<usize> = (0..by_material.len())
        .filter(|&m| by_material[m] > 0.0)
        .collect();
    order.sort_by(|&a, &b| by_material[b].total_cmp(&by_material[a]).then(a.cmp(&b)));
    w.materials = order
        .iter()
        .take(5)
        .map(|&m| (scene.materials[m].name.clone(), by_material[m]))
        .collect();
    w.seconds = start.elapsed().as_secs_f64();
    w
}
