//! The one definition of each light's irradiance at a point (docs/design.md run
//! time step 2), used by the CPU run time, the bake's error lights, the GLSL
//! shaders (`crates/gl/glsl/light.glsl` mirrors [`incident`] line by line) and the
//! path-tracer export.
//!
//! Units: lengths in the scene's unit; a directional light's `irradiance`
//! is what a surface facing it receives (W per scene unit²: W/m² in metre
//! scenes); spot and point `intensity` is in W/sr, so a point light at
//! distance `r` gives `I cos θ / r²`. Irradiance here is the unshadowed
//! value; [`Incident::shadow_end`] is the point a shadow ray must reach
//! unblocked (the light's position, or a point beyond the scene for a
//! directional light).
//!
//! - **Directional**: `E = irradiance · max(0, n · l)`, `l` = minus the
//!   travel direction, normalised.
//! - **Point**: `E = intensity · max(0, n · l) / r²`.
//! - **Spot**: the point light times the profile of Mitsuba 3's `spot`
//!   emitter: 1 within `beam_angle_deg` of the axis, falling linearly in
//!   angle to 0 at `cone_angle_deg` (a continuous falloff; the path tracer
//!   renders exactly this profile), 0 beyond.
//!
//! Emission (`Ke`) is the exitance of a surface and enters `B0 = ρ ∘ D + E`
//! directly; each emissive material's `Ke` can be scaled at run time (the
//! `emission` map of the camera/lights file).

use crate::math::{dot, f64s, normalize, sub};
use crate::scene_config::Light;

/// A light's contribution at a point, before shadowing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Incident {
    /// Irradiance (RGB) on the surface, unshadowed.
    pub irradiance: [f64; 3],
    /// The end of the shadow ray: the light's position, or `x + far · l`.
    pub shadow_end: [f64; 3],
}

/// The spot profile (module doc) at `angle_deg` from the axis.
pub fn spot_profile(angle_deg: f64, cone_deg: f64, beam_deg: f64) -> f64 {
    if angle_deg <= beam_deg {
        1.0
    } else if angle_deg < cone_deg {
        (cone_deg - angle_deg) / (cone_deg - beam_deg)
    } else {
        0.0
    }
}

/// A light with what [`incident`] computes from the light alone done once
/// (f64 values, the normalised direction or axis): per-point work then
/// starts from here, and gives the same bits as from the [`Light`]. Shadow
/// rays cast per sample point and pixel made those normalisations a sixth
/// of a frame's direct light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Prepared {
    Directional {
        /// Towards the light: minus the travel direction, normalised.
        l: [f64; 3],
        irradiance: [f64; 3],
    },
    Point {
        position: [f64; 3],
        intensity: [f64; 3],
    },
    Spot {
        position: [f64; 3],
        /// The normalised axis.
        axis: [f64; 3],
        intensity: [f64; 3],
        cone_deg: f64,
        beam_deg: f64,
        /// Cosines of the axis angle beyond which the profile is surely 0
        /// (below `cos_outside`) or surely 1 (above `cos_inside`): the
        /// cosines of the cone and beam angles moved 1e-9 outwards, far
        /// beyond the rounding of `acos` and of the conversion to degrees,
        /// so that most points skip the `acos` (a few per cent of the
        /// direct pass) and get the bits [`spot_profile`] gives.
        cos_outside: f64,
        cos_inside: f64,
    },
}

impl Prepared {
    pub fn new(light: &Light) -> Prepared {
        match *light {
            Light::Directional {
                direction,
                irradiance,
            } => Prepared::Directional {
                l: normalize(f64s(direction)).map(|c| -c),
                irradiance: f64s(irradiance),
            },
            Light::Point {
                position,
                intensity,
            } => Prepared::Point {
                position: f64s(position),
                intensity: f64s(intensity),
            },
            Light::Spot {
                position,
                direction,
                intensity,
                cone_angle_deg,
                beam_angle_deg,
            } => Prepared::Spot {
                position: f64s(position),
                axis: normalize(f64s(direction)),
                intensity: f64s(intensity),
                cone_deg: cone_angle_deg as f64,
                beam_deg: beam_angle_deg as f64,
                cos_outside: (cone_angle_deg as f64).to_radians().cos() - 1e-9,
                cos_inside: (beam_angle_deg as f64).to_radians().cos() + 1e-9,
            },
        }
    }

    /// Every light of `lights`, prepared.
    pub fn all(lights: &[Light]) -> Vec<Prepared> {
        lights.iter().map(Prepared::new).collect()
    }
}

/// The irradiance `light` puts on a surface at `x` with unit normal `n`,
/// unshadowed (module doc); `None` when it is zero (facing away, outside a
/// spot's cone, or no power). `far` is the length of the shadow ray towards
/// a directional light (beyond the scene's extent).
pub fn incident(light: &Light, x: [f64; 3], n: [f64; 3], far: f64) -> Option<Incident> {
    incident_prepared(&Prepared::new(light), x, n, far)
}

/// [`incident`] of a [`Prepared`] light: the one definition.
pub fn incident_prepared(light: &Prepared, x: [f64; 3], n: [f64; 3], far: f64) -> Option<Incident> {
    match *light {
        Prepared::Directional { l, irradiance } => {
            let cos = dot(n, l);
            if !(cos > 0.0) {
                return None;
            }
            Some(Incident {
                irradiance: irradiance.map(|e| e * cos),
                shadow_end: std::array::from_fn(|k| x[k] + far * l[k]),
            })
        }
        Prepared::Point {
            position,
            intensity,
        } => point(x, n, position, intensity, 1.0),
        Prepared::Spot {
            position,
            axis,
            intensity,
            cone_deg,
            beam_deg,
            cos_outside,
            cos_inside,
        } => {
            let from_light = normalize(sub(x, position));
            let c = dot(axis, from_light).clamp(-1.0, 1.0);
            // The angle θ = acos c changes by at least as much as c does,
            // so 1e-9 of c is 1e-9 rad: surely outside the cone, or inside
            // the beam (Prepared::Spot).
            let profile = if c < cos_outside {
                0.0
            } else if c > cos_inside {
                1.0
            } else {
                spot_profile(c.acos().to_degrees(), cone_deg, beam_deg)
            };
            if !(profile > 0.0) {
                return None;
            }
            point(x, n, position, intensity, profile)
        }
    }
}

fn point(
    x: [f64; 3],
    n: [f64; 3],
    pos: [f64; 3],
    intensity: [f64; 3],
    scale: f64,
) -> Option<Incident> {
    let l = sub(pos, x);
    let r2 = dot(l, l);
    if !(r2 > 0.0) {
        return None;
    }
    let cos = dot(n, l) / r2.sqrt();
    if !(cos > 0.0) {
        return None;
    }
    Some(Incident {
        irradiance: intensity.map(|i| scale * i * cos / r2),
        shadow_end: pos,
    })
}

/// Lanes of [`incident_packet`]: the shadow-ray packets' width.
pub const LANES: usize = 8;

/// [`incident_prepared`] at up to [`LANES`] points at once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IncidentPacket {
    /// Lane `k` set where point `k` is live and lit (unshadowed): the
    /// lanes [`incident_prepared`] answers `Some` for.
    pub mask: u8,
    /// Per lane, the irradiance (0 where the lane is not in `mask`).
    pub irradiance: [[f64; 3]; LANES],
    /// Per lane, the shadow ray's direction `shadow_end − x`, as the
    /// caller of [`incident_prepared`] computes it (0 outside `mask`).
    pub dir: [[f64; 3]; LANES],
}

/// [`incident_prepared`] at the points `x[k]` with unit normals `n[k]` for
/// the lanes `k` set in `live`, with the same bits lane by lane: every
/// lane runs the same operations in the same order (IEEE operations, no
/// fused multiply-add, so a vector lane rounds as the scalar code does),
/// written over arrays with selects instead of branches so that the
/// compiler vectorises them (on AVX-512 one instruction serves the eight
/// lanes). A spot's penumbra, where the profile needs `acos`, is finished
/// lane by lane through [`spot_profile`] as [`incident_prepared`] does.
/// The direct pass called [`incident_prepared`] per sample point, a fifth
/// of its time in chains of divisions and square roots.
pub fn incident_packet(
    light: &Prepared,
    x: &[[f64; 3]; LANES],
    n: &[[f64; 3]; LANES],
    far: f64,
    live: u8,
) -> IncidentPacket {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU reports AVX-512F.
            return unsafe { incident_packet_avx512(light, x, n, far, live) };
        }
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU reports AVX2.
            return unsafe { incident_packet_avx2(light, x, n, far, live) };
        }
    }
    incident_packet_lanes(light, x, n, far, live)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn incident_packet_avx512(
    light: &Prepared,
    x: &[[f64; 3]; LANES],
    n: &[[f64; 3]; LANES],
    far: f64,
    live: u8,
) -> IncidentPacket {
    incident_packet_lanes(light, x, n, far, live)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn incident_packet_avx2(
    light: &Prepared,
    x: &[[f64; 3]; LANES],
    n: &[[f64; 3]; LANES],
    far: f64,
    live: u8,
) -> IncidentPacket {
    incident_packet_lanes(light, x, n, far, live)
}

/// Eight values, one per lane.
type Lanes = [f64; LANES];

/// `f` per lane.
#[inline(always)]
fn lanes(f: impl Fn(usize) -> f64) -> Lanes {
    std::array::from_fn(f)
}

/// `a · b` per lane, as [`dot`] orders it.
#[inline(always)]
fn dot_lanes(a: &[Lanes; 3], b: &[Lanes; 3]) -> Lanes {
    lanes(|k| a[0][k] * b[0][k] + a[1][k] * b[1][k] + a[2][k] * b[2][k])
}

/// The body of [`incident_packet`], inlined into each instruction set's
/// copy.
#[inline(always)]
fn incident_packet_lanes(
    light: &Prepared,
    x: &[[f64; 3]; LANES],
    n: &[[f64; 3]; LANES],
    far: f64,
    live: u8,
) -> IncidentPacket {
    // By coordinate, lanes side by side.
    let xs: [Lanes; 3] = std::array::from_fn(|c| lanes(|k| x[k][c]));
    let ns: [Lanes; 3] = std::array::from_fn(|c| lanes(|k| n[k][c]));
    let (ok, e, end): ([bool; LANES], [Lanes; 3], [Lanes; 3]) = match *light {
        Prepared::Directional { l, irradiance } => {
            let ls = l.map(|v| [v; LANES]);
            let cos = dot_lanes(&ns, &ls);
            (
                std::array::from_fn(|k| cos[k] > 0.0),
                std::array::from_fn(|c| lanes(|k| irradiance[c] * cos[k])),
                std::array::from_fn(|c| lanes(|k| xs[c][k] + far * l[c])),
            )
        }
        Prepared::Point {
            position,
            intensity,
        } => point_lanes(&xs, &ns, position, intensity, &[1.0; LANES]),
        Prepared::Spot {
            position,
            axis,
            intensity,
            cone_deg,
            beam_deg,
            cos_outside,
            cos_inside,
        } => {
            // normalize(x − position), then the axis cosine, clamped.
            let d: [Lanes; 3] = std::array::from_fn(|c| lanes(|k| xs[c][k] - position[c]));
            let len = lanes(|k| (d[0][k] * d[0][k] + d[1][k] * d[1][k] + d[2][k] * d[2][k]).sqrt());
            let f: [Lanes; 3] = std::array::from_fn(|c| lanes(|k| d[c][k] / len[k]));
            let axes = axis.map(|v| [v; LANES]);
            let c = dot_lanes(&axes, &f).map(|v| v.clamp(-1.0, 1.0));
            let mut profile = lanes(|k| if c[k] < cos_outside { 0.0 } else { 1.0 });
            for k in 0..LANES {
                // The penumbra (and NaN), where `acos` decides.
                if live >> k & 1 != 0 && !(c[k] < cos_outside) && !(c[k] > cos_inside) {
                    profile[k] = spot_profile(c[k].acos().to_degrees(), cone_deg, beam_deg);
                }
            }
            let (ok, e, end) = point_lanes(&xs, &ns, position, intensity, &profile);
            (std::array::from_fn(|k| ok[k] && profile[k] > 0.0), e, end)
        }
    };
    let mut out = IncidentPacket {
        mask: 0,
        irradiance: [[0.0; 3]; LANES],
        dir: [[0.0; 3]; LANES],
    };
    for k in 0..LANES {
        if live >> k & 1 != 0 && ok[k] {
            out.mask |= 1 << k;
            out.irradiance[k] = std::array::from_fn(|c| e[c][k]);
            out.dir[k] = std::array::from_fn(|c| end[c][k] - x[k][c]);
        }
    }
    out
}

/// [`point`] per lane: whether lit, the irradiance and the shadow ray's end.
#[inline(always)]
fn point_lanes(
    xs: &[Lanes; 3],
    ns: &[Lanes; 3],
    pos: [f64; 3],
    intensity: [f64; 3],
    scale: &Lanes,
) -> ([bool; LANES], [Lanes; 3], [Lanes; 3]) {
    let l: [Lanes; 3] = std::array::from_fn(|c| lanes(|k| pos[c] - xs[c][k]));
    let r2 = dot_lanes(&l, &l);
    let nl = dot_lanes(ns, &l);
    let cos = lanes(|k| nl[k] / r2[k].sqrt());
    (
        std::array::from_fn(|k| r2[k] > 0.0 && cos[k] > 0.0),
        std::array::from_fn(|c| lanes(|k| scale[k] * intensity[c] * cos[k] / r2[k])),
        std::array::from_fn(|c| [pos[c]; LANES]),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::SplitMix64;

    /// Each light type at random points and normals (some at the light's
    /// position, some facing away, a third of a spot's points within 1e-6°
    /// of its cone or beam boundary, scene scales from 1e-3 to 1e3), with
    /// random live lanes: every instruction set's packet gives, lane by
    /// lane, the bits [`incident_prepared`] gives, and nothing on lanes it
    /// answers `None` for or that are not live.
    /// One instruction set's [`incident_packet`].
    type PacketFn =
        fn(&Prepared, &[[f64; 3]; LANES], &[[f64; 3]; LANES], f64, u8) -> IncidentPacket;

    #[test]
    fn packets_give_the_scalar_bits() {
        let mut rng = SplitMix64::new(7);
        fn u(rng: &mut SplitMix64, a: f64, b: f64) -> f64 {
            a + (b - a) * rng.uniform()
        }
        fn v3(rng: &mut SplitMix64, r: f64) -> [f64; 3] {
            [u(rng, -r, r), u(rng, -r, r), u(rng, -r, r)]
        }
        let mut kinds: Vec<(&str, PacketFn)> = vec![
            ("portable", |l, x, n, f, m| {
                incident_packet_lanes(l, x, n, f, m)
            }),
            ("dispatch", incident_packet),
        ];
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU reports AVX2.
                kinds.push(("avx2", |l, x, n, f, m| unsafe {
                    incident_packet_avx2(l, x, n, f, m)
                }));
            }
            if std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: the CPU reports AVX-512F.
                kinds.push(("avx512", |l, x, n, f, m| unsafe {
                    incident_packet_avx512(l, x, n, f, m)
                }));
            }
        }
        let (mut lit, mut penumbra) = (0usize, 0usize);
        for trial in 0..4000 {
            let s = 10f64.powf(u(&mut rng, -3.0, 3.0));
            let pos = v3(&mut rng, s);
            let unit = |v: [f64; 3]| normalize(v);
            let dir = unit(v3(&mut rng, 1.0));
            let (cone, beam) = (u(&mut rng, 1.0, 89.0), 0.0);
            let beam = beam + cone * u(&mut rng, 0.0, 1.0);
            let light = match trial % 3 {
                0 => Light::Directional {
                    direction: dir.map(|c| c as f32),
                    irradiance: [1.7, 0.3, 2.9],
                },
                1 => Light::Point {
                    position: pos.map(|c| c as f32),
                    intensity: [3.1, 0.7, 1.3],
                },
                _ => Light::Spot {
                    position: pos.map(|c| c as f32),
                    direction: dir.map(|c| c as f32),
                    intensity: [2.3, 1.9, 0.3],
                    cone_angle_deg: cone as f32,
                    beam_angle_deg: beam as f32,
                },
            };
            let p = Prepared::new(&light);
            let mut x = [[0.0; 3]; LANES];
            let mut n = [[0.0; 3]; LANES];
            for k in 0..LANES {
                let lp = f64s(match light {
                    Light::Point { position, .. } | Light::Spot { position, .. } => position,
                    _ => [0.0; 3],
                });
                x[k] = match k % 4 {
                    // At the light (r² = 0).
                    0 if trial % 7 == 0 => lp,
                    // On a spot's cone or beam boundary, within 1e-6°.
                    1 | 2 if matches!(p, Prepared::Spot { .. }) => {
                        let Prepared::Spot {
                            axis,
                            cone_deg,
                            beam_deg,
                            ..
                        } = p
                        else {
                            unreachable!()
                        };
                        let a = (if k == 1 { cone_deg } else { beam_deg }
                            + u(&mut rng, -1e-6, 1e-6))
                        .to_radians();
                        // A unit vector perpendicular to the axis.
                        let t = normalize(crate::math::cross(axis, v3(&mut rng, 1.0)));
                        let r = u(&mut rng, 0.1, 2.0) * s;
                        std::array::from_fn(|c| lp[c] + r * (a.cos() * axis[c] + a.sin() * t[c]))
                    }
                    _ => v3(&mut rng, 2.0 * s),
                };
                n[k] = unit(v3(&mut rng, 1.0));
            }
            let live = (rng.next_u64() & 0xff) as u8 | 1;
            let far = 4.0 * s;
            for (name, f) in &kinds {
                let pk = f(&p, &x, &n, far, live);
                for k in 0..LANES {
                    let want = (live >> k & 1 != 0)
                        .then(|| incident_prepared(&p, x[k], n[k], far))
                        .flatten();
                    let got = (pk.mask >> k & 1 != 0).then(|| Incident {
                        irradiance: pk.irradiance[k],
                        shadow_end: std::array::from_fn(|c| x[k][c] + pk.dir[k][c]),
                    });
                    match (want, got) {
                        (None, None) => {
                            assert_eq!(
                                (pk.irradiance[k], pk.dir[k]),
                                ([0.0; 3], [0.0; 3]),
                                "{name}"
                            );
                        }
                        (Some(w), Some(g)) => {
                            lit += 1;
                            assert_eq!(
                                w.irradiance.map(f64::to_bits),
                                g.irradiance.map(f64::to_bits),
                                "{name} trial {trial} lane {k}"
                            );
                            let wd = crate::math::sub(w.shadow_end, x[k]);
                            assert_eq!(
                                wd.map(f64::to_bits),
                                pk.dir[k].map(f64::to_bits),
                                "{name} trial {trial} lane {k}"
                            );
                            if let Prepared::Spot {
                                cos_outside,
                                cos_inside,
                                position,
                                axis,
                                ..
                            } = p
                            {
                                let c = crate::math::dot(
                                    axis,
                                    normalize(crate::math::sub(x[k], position)),
                                );
                                penumbra += usize::from(c >= cos_outside && c <= cos_inside);
                            }
                        }
                        (w, g) => panic!("{name} trial {trial} lane {k}: {w:?} against {g:?}"),
                    }
                }
            }
        }
        // The test reached lit lanes and the acos path.
        assert!(
            lit > 10_000 && penumbra > 1_000,
            "lit {lit}, penumbra {penumbra}"
        );
    }
}
