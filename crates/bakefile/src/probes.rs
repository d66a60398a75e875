//! The optional `PROB` section: irradiance probes on a regular grid in the
//! scene's space, each with a sparse transfer from what it sees to its
//! incident radiance in band-2 (L2, 9 coefficients) real spherical
//! harmonics ([`radiosity_core::sh`]). Moving objects are lit from them
//! (issue 46, `docs/probes.md`).
//!
//! A probe casts `rays` uniformly spread directions `ω_k` (a spherical
//! Fibonacci set, pdf `1/4π`). A ray that meets patch `j` sees its
//! radiance `B_j/π` (Lambertian exitance `B = B0 + ρ∘H`); one that leaves
//! the scene through sky cell `c` ([`radiosity_core::sky::cells`]) sees the
//! sky's mean radiance there `L̄_c`. The probe's radiance coefficients are
//! then `L_lm = Σ_j w_jlm B_j + Σ_c s_clm L̄_c` with the Monte Carlo
//! weights `w_jlm = (4π/N)(1/π) Σ_{k→j} Y_lm(ω_k)` and
//! `s_clm = (4π/N) Σ_{k→c} Y_lm(ω_k)`; its irradiance about a normal `n`
//! is `E(n) = Σ_lm Â_l L_lm Y_lm(n)` with `Â = (π, 2π/3, π/4)`
//! (Ramamoorthi and Hanrahan 2001).
//!
//! **Stored as amount and mean direction.** An entry keeps not its nine
//! weights but four numbers: the amount `a` (`4 k/N` for a patch met by
//! `k` of the `N` rays, `4π k/N` for a sky cell) and the mean of the
//! rays' directions `m = Σ ω/k` (`|m| ≤ 1`). Bands 0 and 1 are linear in
//! `ω`, so `w_00 = a Y_00` and `w_1m = a Y_1m(m)` are exact; band 2 is
//! taken as a spherical cap's, `w_2m = a Y_2m(m̂) |m|(2|m| − 1)`, exact
//! when the rays fill a cap around `m̂` (its mean direction has length
//! `(1 + cos α)/2` and its band-2 mean `P_2`-weight `cos α (1 + cos α)/2`).
//! Entries are then 20 bytes instead of 40, and the run time's update reads
//! half as much; [`weights`] is the decoding both run times follow, and
//! `tests/probes.rs` measures the whole against 65,536 brute-force rays.
//!
//! **Emission seen exactly.** A ray that meets an emissive face also adds
//! to an entry of the face's material, whose radiance is the material's
//! `Ke/π` times its run-time scale; the patch entries then carry the
//! patches' reflected exitance `B − E` alone. A patch's `E` is the area
//! mean of what emits in it, so a probe beside an emitter that fills part
//! of a voxel face would otherwise see its light spread over the whole
//! face (the Cornell box's probe 11 mm under the ceiling and 23 mm beside
//! its light was 70 % too bright upwards).
//!
//! A probe whose rays meet the back of surfaces (more than
//! [`SOLID_FRACTION`] of them) is inside a solid or outside a closed scene:
//! it is marked [`ProbeState::Solid`] and stores nothing; the run time
//! never interpolates from it. One whose rays mostly leave the scene
//! (more than [`OPEN_FRACTION`]) is marked [`ProbeState::Open`]: above an
//! open scene's roofs, lit by the sky, and used like any other.
//!
//! Layout (little-endian): version `u32` (= [`PROBE_VERSION`]), rays per
//! probe `u32`, grid dimensions `u32 × 3` (`P` = their product, x
//! fastest), patch entries `m` `u32`, sky entries `s` `u32`, emission
//! entries `e` `u32`; the grid's first probe `f32 × 3` and spacing `f32`;
//! then `P` states `u8`; `P + 1` starts `u32`, `m` patches `u32` (file
//! order), `m` entries `(a, m_x, m_y, m_z)` `f32 × 4`; `P + 1` sky starts
//! `u32`, `s` cells `u8`, `s` entries `f32 × 4`; `P + 1` emission starts
//! `u32`, `e` materials `u32` (the scene's material indices), `e` entries
//! `f32 × 4`. Version 1 (this layout without emission entries, a zero in
//! their count's place) reads as none: bake again.

use crate::section_error::SectionError;
use radiosity_core::sh::{basis, COEFFICIENTS};
use radiosity_core::sky::cells::CELLS;

/// The layout version this build writes and reads.
pub const PROBE_VERSION: u32 = 2;

/// Header bytes.
const HEADER: usize = 48;

/// More than this fraction of a probe's rays on the back of surfaces marks
/// it [`ProbeState::Solid`]: a probe in a room sees backs only where the
/// scene's own faces are wound inwards and one-sided, which the bake's
/// winding check repairs (`bake::winding`); a quarter leaves room for what
/// it does not.
pub const SOLID_FRACTION: f64 = 0.25;

/// More than this fraction of a probe's rays leaving the scene marks it
/// [`ProbeState::Open`].
pub const OPEN_FRACTION: f64 = 0.5;

/// Where a probe is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum ProbeState {
    /// In the scene's empty space: used.
    Valid = 0,
    /// In a solid, or outside a closed scene: never used, stores nothing.
    Solid = 1,
    /// Mostly under the open sky (outside an open scene): used.
    Open = 2,
}

impl ProbeState {
    /// Whether the run time interpolates from it.
    pub fn is_used(self) -> bool {
        self != ProbeState::Solid
    }

    fn from_u8(b: u8) -> Option<ProbeState> {
        match b {
            0 => Some(ProbeState::Valid),
            1 => Some(ProbeState::Solid),
            2 => Some(ProbeState::Open),
            _ => None,
        }
    }
}

/// A regular grid of probes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ProbeGrid {
    /// Probes along x, y and z.
    pub dims: [u32; 3],
    /// Probe `(0, 0, 0)`'s position.
    pub origin: [f32; 3],
    /// The distance between neighbouring probes along each axis.
    pub spacing: f32,
}

impl ProbeGrid {
    /// Probes in the grid.
    pub fn len(&self) -> usize {
        self.dims.iter().map(|&d| d as usize).product()
    }

    /// Whether it has none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Probe `(i, j, k)`'s index.
    pub fn index(&self, c: [u32; 3]) -> usize {
        c[0] as usize
            + self.dims[0] as usize * (c[1] as usize + self.dims[1] as usize * c[2] as usize)
    }

    /// Probe `p`'s position.
    pub fn position(&self, p: usize) -> [f64; 3] {
        let d = self.dims.map(|d| d as usize);
        let c = [p % d[0], (p / d[0]) % d[1], p / (d[0] * d[1])];
        std::array::from_fn(|a| f64::from(self.origin[a]) + f64::from(self.spacing) * c[a] as f64)
    }
}

/// One entry's weights `w_lm` from its amount `a` and mean direction `m`
/// (module doc), in [`radiosity_core::sh::basis`]'s order.
pub fn weights(e: [f32; 4]) -> [f32; COEFFICIENTS] {
    let a = f64::from(e[0]);
    let m = [e[1], e[2], e[3]].map(f64::from);
    let len = (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt();
    if !(len > 0.0) {
        // Rays from all around (mean 0): band 0 only.
        let mut w = [0.0; COEFFICIENTS];
        w[0] = (a * 0.282_094_791_773_878_14) as f32;
        return w;
    }
    let b = basis(m.map(|x| x / len));
    let band2 = len * (2.0 * len - 1.0);
    std::array::from_fn(|l| {
        let f = match l {
            0 => 1.0,
            1..=3 => len,
            _ => band2,
        };
        (a * f * b[l]) as f32
    })
}

/// The probes and their transfers (module doc).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Probes {
    /// Rays cast per probe (0: no section).
    pub rays: u32,
    pub grid: ProbeGrid,
    /// Per probe.
    pub states: Vec<ProbeState>,
    /// `P + 1` offsets into `patches` and `weights` (by 9).
    pub starts: Vec<u32>,
    /// The patch of each entry.
    pub patches: Vec<u32>,
    /// `(a, m)` of each entry.
    pub entries: Vec<[f32; 4]>,
    /// `P + 1` offsets into `sky_cells` and `sky_entries`.
    pub sky_starts: Vec<u32>,
    pub sky_cells: Vec<u8>,
    /// `(a, m)` of each sky entry.
    pub sky_entries: Vec<[f32; 4]>,
    /// `P + 1` offsets into `emitters` and `emission_entries`.
    pub emission_starts: Vec<u32>,
    /// The emissive material of each emission entry.
    pub emitters: Vec<u32>,
    /// `(a, m)` of each emission entry.
    pub emission_entries: Vec<[f32; 4]>,
}

/// One probe's entries as the bake makes them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ProbeEntries {
    pub state: Option<ProbeState>,
    /// `(patch, (a, m))`, patches increasing.
    pub patches: Vec<(u32, [f32; 4])>,
    /// `(cell, (a, m))`, cells increasing.
    pub sky: Vec<(u8, [f32; 4])>,
    /// `(material, (a, m))` of the emissive faces met, materials
    /// increasing.
    pub emission: Vec<(u32, [f32; 4])>,
}

impl Probes {
    /// No probes (a bake made without them).
    pub fn none() -> Probes {
        Probes::default()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.rays == 0
    }

    /// Probes in the grid.
    pub fn len(&self) -> usize {
        self.states.len()
    }

    /// From each probe's entries (grid order).
    pub fn from_entries(rays: u32, grid: ProbeGrid, probes: &[ProbeEntries]) -> Probes {
        let mut s = Probes {
            rays,
            grid,
            starts: vec![0],
            sky_starts: vec![0],
            emission_starts: vec![0],
            ..Probes::default()
        };
        for p in probes {
            s.states.push(p.state.unwrap_or(ProbeState::Valid));
            for (j, e) in &p.patches {
                s.patches.push(*j);
                s.entries.push(*e);
            }
            for (c, e) in &p.sky {
                s.sky_cells.push(*c);
                s.sky_entries.push(*e);
            }
            for (m, e) in &p.emission {
                s.emitters.push(*m);
                s.emission_entries.push(*e);
            }
            s.starts.push(s.patches.len() as u32);
            s.sky_starts.push(s.sky_cells.len() as u32);
            s.emission_starts.push(s.emitters.len() as u32);
        }
        s
    }

    /// Probe `p`'s patch entries: `(patch, (a, m))`.
    pub fn patch_entries(&self, p: usize) -> impl Iterator<Item = (usize, [f32; 4])> + '_ {
        let (a, b) = (self.starts[p] as usize, self.starts[p + 1] as usize);
        (a..b).map(|k| (self.patches[k] as usize, self.entries[k]))
    }

    /// Probe `p`'s sky entries: `(cell, (a, m))`.
    pub fn sky_entries_of(&self, p: usize) -> impl Iterator<Item = (usize, [f32; 4])> + '_ {
        let (a, b) = (self.sky_starts[p] as usize, self.sky_starts[p + 1] as usize);
        (a..b).map(|k| (usize::from(self.sky_cells[k]), self.sky_entries[k]))
    }

    /// Probe `p`'s emission entries: `(material, (a, m))`.
    pub fn emission_entries_of(&self, p: usize) -> impl Iterator<Item = (usize, [f32; 4])> + '_ {
        let (a, b) = (
            self.emission_starts[p] as usize,
            self.emission_starts[p + 1] as usize,
        );
        (a..b).map(|k| (self.emitters[k] as usize, self.emission_entries[k]))
    }

    /// The section's bytes (module doc).
    pub fn to_bytes(&self) -> Vec<u8> {
        let (m, s) = (self.patches.len(), self.sky_cells.len());
        let mut out = Vec::new();
        let g = &self.grid;
        for v in [
            PROBE_VERSION,
            self.rays,
            g.dims[0],
            g.dims[1],
            g.dims[2],
            m as u32,
            s as u32,
            self.emitters.len() as u32,
        ] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for v in [g.origin[0], g.origin[1], g.origin[2], g.spacing] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend(self.states.iter().map(|&s| s as u8));
        let put_u32 = |out: &mut Vec<u8>, v: &[u32]| {
            for x in v {
                out.extend_from_slice(&x.to_le_bytes());
            }
        };
        let put_f32 = |out: &mut Vec<u8>, v: &[f32]| {
            for x in v {
                out.extend_from_slice(&x.to_le_bytes());
            }
        };
        put_u32(&mut out, &self.starts);
        put_u32(&mut out, &self.patches);
        put_f32(&mut out, self.entries.as_flattened());
        put_u32(&mut out, &self.sky_starts);
        out.extend_from_slice(&self.sky_cells);
        put_f32(&mut out, self.sky_entries.as_flattened());
        put_u32(&mut out, &self.emission_starts);
        put_u32(&mut out, &self.emitters);
        put_f32(&mut out, self.emission_entries.as_flattened());
        out
    }

    /// Reads `PROB` for a file of `n` patches; every field is checked
    /// ([`Probes::check`]).
    pub fn from_bytes(b: &[u8], n: usize) -> Result<Probes, SectionError> {
        if b.len() < HEADER {
            return Err(SectionError::Truncated {
                what: "header",
                need: HEADER as u64,
                at: 0,
                left: b.len() as u64,
            });
        }
        let u32_at = |at: usize| u32::from_le_bytes(b[at..at + 4].try_into().expect("4 bytes"));
        let f32_at = |at: usize| f32::from_bits(u32_at(at));
        let version = u32_at(0);
        if version == 1 {
            return Ok(Probes::none());
        }
        if version != PROBE_VERSION {
            return Err(SectionError::Unsupported(format!(
                "layout version {version}; this build reads version {PROBE_VERSION}"
            )));
        }
        let rays = u32_at(4);
        let dims = [u32_at(8), u32_at(12), u32_at(16)];
        let (m, s, e) = (u32_at(20) as u64, u32_at(24) as u64, u32_at(28) as u64);
        let grid = ProbeGrid {
            dims,
            origin: [f32_at(32), f32_at(36), f32_at(40)],
            spacing: f32_at(44),
        };
        let p = dims.iter().map(|&d| d as u64).product::<u64>();
        let expected = HEADER as u64 + p + 3 * 4 * (p + 1) + 20 * m + 17 * s + 20 * e;
        if b.len() as u64 != expected {
            return Err(SectionError::Length {
                found: b.len() as u64,
                expected,
                layout: format!(
                    "{p} probes, {m} patch entries, {s} sky entries and {e} emission entries"
                ),
            });
        }
        let (p, m, s, e) = (p as usize, m as usize, s as usize, e as usize);
        let mut at = HEADER;
        let mut states = Vec::with_capacity(p);
        for (k, &byte) in b[at..at + p].iter().enumerate() {
            states.push(ProbeState::from_u8(byte).ok_or_else(|| {
                SectionError::Invalid(format!("probe {k}: state {byte} (0, 1 or 2)"))
            })?);
        }
        at += p;
        let u32s = |count: usize, at: &mut usize| -> Vec<u32> {
            let v = (0..count).map(|k| u32_at(*at + 4 * k)).collect();
            *at += 4 * count;
            v
        };
        let starts = u32s(p + 1, &mut at);
        let patches = u32s(m, &mut at);
        let quads = |v: Vec<u32>| -> Vec<[f32; 4]> {
            v.chunks_exact(4)
                .map(|c| std::array::from_fn(|i| f32::from_bits(c[i])))
                .collect()
        };
        let entries = quads(u32s(4 * m, &mut at));
        let sky_starts = u32s(p + 1, &mut at);
        let sky_cells = b[at..at + s].to_vec();
        at += s;
        let sky_entries = quads(u32s(4 * s, &mut at));
        let emission_starts = u32s(p + 1, &mut at);
        let emitters = u32s(e, &mut at);
        let emission_entries = quads(u32s(4 * e, &mut at));
        let probes = Probes {
            rays,
            grid,
            states,
            starts,
            patches,
            entries,
            sky_starts,
            sky_cells,
            sky_entries,
            emission_starts,
            emitters,
            emission_entries,
        };
        probes.check(n)?;
        Ok(probes)
    }

    /// Checks the fields: a grid with probes and a finite origin and
    /// positive spacing; starts from 0 to the entries, never decreasing;
    /// patches below `n` and cells below the sky's, increasing within a
    /// probe; a solid probe without entries; amounts positive and finite,
    /// a probe's summing to at most the whole sphere's (4 for patches, 4π
    /// for cells) with f32 slack; mean directions finite and at most 1
    /// long.
    pub fn check(&self, n: usize) -> Result<(), SectionError> {
        let invalid = |s: String| Err(SectionError::Invalid(s));
        if self.rays == 0 {
            return if self.states.is_empty() && self.patches.is_empty() {
                Ok(())
            } else {
                invalid(format!("{} probes stored for 0 rays", self.states.len()))
            };
        }
        let g = &self.grid;
        let p = g.len();
        if p == 0
            || !g.origin.iter().all(|x| x.is_finite())
            || !(g.spacing.is_finite() && g.spacing > 0.0)
        {
            return invalid(format!(
                "grid of {:?} probes from {:?} spaced {}: needs probes, a finite origin and a \
                 positive spacing",
                g.dims, g.origin, g.spacing
            ));
        }
        let (m, s) = (self.patches.len(), self.sky_cells.len());
        if self.states.len() != p
            || self.starts.len() != p + 1
            || self.sky_starts.len() != p + 1
            || self.emission_starts.len() != p + 1
            || self.entries.len() != m
            || self.sky_entries.len() != s
            || self.emission_entries.len() != self.emitters.len()
        {
            return invalid(format!(
                "{} states, {} starts, {} sky starts, {} emission starts for {p} probes",
                self.states.len(),
                self.starts.len(),
                self.sky_starts.len(),
                self.emission_starts.len()
            ));
        }
        let slack = 1.0 + 8.0 * f64::from(f32::EPSILON) * f64::from(self.rays);
        for (starts, count, what, limit) in [
            (&self.starts, m, "patch", 4.0),
            (&self.sky_starts, s, "sky", 4.0 * std::f64::consts::PI),
            (&self.emission_starts, self.emitters.len(), "emission", 4.0),
        ] {
            if starts[0] != 0 || starts[p] as usize != count {
                return invalid(format!(
                    "{what} starts run from {} to {}, not 0 to {count}",
                    starts[0], starts[p]
                ));
            }
            for i in 0..p {
                let (a, b) = (starts[i] as usize, starts[i + 1] as usize);
                if a > b {
                    return invalid(format!("probe {i}: {what} starts decrease ({a} > {b})"));
                }
                if a < b && self.states[i] == ProbeState::Solid {
                    return invalid(format!("probe {i}: solid, with {what} entries"));
                }
                let mut total = 0.0;
                for k in a..b {
                    let (idx, ok) = match what {
                        "patch" => {
                            let j = self.patches[k] as usize;
                            (
                                j,
                                j < n && (k == a || self.patches[k - 1] < self.patches[k]),
                            )
                        }
                        "sky" => {
                            let c = usize::from(self.sky_cells[k]);
                            (
                                c,
                                c < CELLS && (k == a || self.sky_cells[k - 1] < self.sky_cells[k]),
                            )
                        }
                        _ => {
                            let q = self.emitters[k] as usize;
                            (q, k == a || self.emitters[k - 1] < self.emitters[k])
                        }
                    };
                    if !ok {
                        return invalid(format!(
                            "probe {i}: {what} {idx} out of order or out of range"
                        ));
                    }
                    let e = match what {
                        "patch" => self.entries[k],
                        "sky" => self.sky_entries[k],
                        _ => self.emission_entries[k],
                    };
                    let len2: f32 = e[1] * e[1] + e[2] * e[2] + e[3] * e[3];
                    if !e.iter().all(|x| x.is_finite())
                        || !(e[0] > 0.0)
                        || len2 > 1.0 + 4.0 * f32::EPSILON
                    {
                        return invalid(format!(
                            "probe {i}: {what} {idx} has amount and mean direction {e:?}"
                        ));
                    }
                    total += f64::from(e[0]);
                }
                if total > limit * slack {
                    return invalid(format!(
                        "probe {i}: its {what} entries' amounts sum to {total}, more than the \
                         whole sphere's {limit}"
                    ));
                }
            }
        }
        Ok(())
    }

    /// The probes with patches renumbered: entry patch `j` becomes
    /// `new_of[j]` (entries re-sorted).
    pub fn renumbered(&self, new_of: &[u32]) -> Probes {
        if self.is_empty() {
            return Probes::none();
        }
        let mut out = self.clone();
        for p in 0..self.len() {
            let (a, b) = (self.starts[p] as usize, self.starts[p + 1] as usize);
            let mut e: Vec<(u32, usize)> = (a..b)
                .map(|k| (new_of[self.patches[k] as usize], k))
                .collect();
            e.sort_unstable();
            for (slot, (j, k)) in (a..b).zip(e) {
                out.patches[slot] = j;
                out.entries[slot] = self.entries[k];
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Probes {
        let w = |x: f32| [x, 0.0, -0.5, 0.5];
        Probes::from_entries(
            64,
            ProbeGrid {
                dims: [3, 1, 1],
                origin: [0.0, 1.0, 2.0],
                spacing: 0.5,
            },
            &[
                ProbeEntries {
                    state: Some(ProbeState::Valid),
                    patches: vec![(0, w(0.3)), (2, w(0.2))],
                    sky: vec![(7, w(1.0))],
                    emission: vec![(4, w(0.1))],
                },
                ProbeEntries {
                    state: Some(ProbeState::Solid),
                    ..ProbeEntries::default()
                },
                ProbeEntries {
                    state: Some(ProbeState::Open),
                    patches: vec![(1, w(0.1))],
                    sky: vec![],
                    emission: vec![],
                },
            ],
        )
    }

    #[test]
    fn bytes_round_trip_and_faults_are_named() {
        let s = sample();
        let b = s.to_bytes();
        assert_eq!(Probes::from_bytes(&b, 3).unwrap(), s);
        assert!(matches!(
            Probes::from_bytes(&b[..10], 3),
            Err(SectionError::Truncated { .. })
        ));
        assert!(matches!(
            Probes::from_bytes(&b[..b.len() - 1], 3),
            Err(SectionError::Length { .. })
        ));
        // Version 1 (no emission entries) reads as none.
        let mut older = b.clone();
        older[0] = 1;
        assert!(Probes::from_bytes(&older, 3).unwrap().is_empty());
        assert_eq!(s.emission_entries_of(0).count(), 1);
        let mut newer = b.clone();
        newer[0] = 3;
        assert!(matches!(
            Probes::from_bytes(&newer, 3),
            Err(SectionError::Unsupported(_))
        ));
        // A patch beyond the file's.
        assert!(Probes::from_bytes(&b, 2)
            .unwrap_err()
            .to_string()
            .contains("probe 0: patch 2"));
        let mut bad = s.clone();
        bad.states[0] = ProbeState::Solid;
        assert!(bad.check(3).unwrap_err().to_string().contains("solid"));
        let mut bad = s.clone();
        bad.entries[0][0] = 4.0;
        assert!(bad
            .check(3)
            .unwrap_err()
            .to_string()
            .contains("whole sphere"));
        let mut bad = s.clone();
        bad.entries[0][2] = f32::NAN;
        assert!(bad
            .check(3)
            .unwrap_err()
            .to_string()
            .contains("probe 0: patch 0"));
        // Emission entries are checked as their own list (two in order,
        // then out of order).
        let mut two = s.clone();
        two.emitters = vec![4, 9];
        two.emission_entries = vec![[0.1, 0.0, 0.0, 0.0]; 2];
        two.emission_starts = vec![0, 2, 2, 2];
        two.check(3).unwrap();
        two.emitters = vec![9, 4];
        assert!(two
            .check(3)
            .unwrap_err()
            .to_string()
            .contains("emission 4 out of order"));
        let mut bad = s.clone();
        bad.entries[0][1] = 1.0;
        assert!(bad
            .check(3)
            .unwrap_err()
            .to_string()
            .contains("mean direction"));
        let mut bad = s.to_bytes();
        bad[HEADER] = 9;
        assert!(Probes::from_bytes(&bad, 3)
            .unwrap_err()
            .to_string()
            .contains("state 9"));
    }

    #[test]
    fn renumbering_keeps_each_patch_its_weights() {
        let s = sample();
        let r = s.renumbered(&[2, 0, 1]);
        let e: Vec<(usize, f32)> = r.patch_entries(0).map(|(j, e)| (j, e[0])).collect();
        assert_eq!(e, vec![(1, 0.2), (2, 0.3)]);
        r.check(3).unwrap();
        assert_eq!(s.grid.position(2), [1.0, 1.0, 2.0]);
        assert_eq!(s.grid.index([2, 0, 0]), 2);
    }

    /// The decoding is exact for a spherical cap of rays: the weights of a
    /// dense set of directions within 50° of an axis against the mean of
    /// the basis over them.
    #[test]
    fn amount_and_mean_direction_are_exact_for_a_cap() {
        let axis = radiosity_core::math::normalize([0.3, 0.8, -0.52]);
        let (u, v) = radiosity_core::math::tangent_basis(axis);
        let cos_a = 50f64.to_radians().cos();
        let (rings, seg) = (400, 400);
        let mut sum = [0.0f64; COEFFICIENTS];
        let mut mean = [0.0f64; 3];
        let mut total = 0.0;
        for r in 0..rings {
            // Uniform in solid angle: equal steps in cos θ.
            let c = 1.0 - (1.0 - cos_a) * (r as f64 + 0.5) / rings as f64;
            let sn = (1.0 - c * c).sqrt();
            for k in 0..seg {
                let phi = 2.0 * std::f64::consts::PI * (k as f64 + 0.5) / seg as f64;
                let d: [f64; 3] = std::array::from_fn(|i| {
                    c * axis[i] + sn * (phi.cos() * u[i] + phi.sin() * v[i])
                });
                for (s, b) in sum.iter_mut().zip(basis(d)) {
                    *s += b;
                }
                for i in 0..3 {
                    mean[i] += d[i];
                }
                total += 1.0;
            }
        }
        let e = [
            1.0,
            (mean[0] / total) as f32,
            (mean[1] / total) as f32,
            (mean[2] / total) as f32,
        ];
        let w = weights(e);
        for l in 0..COEFFICIENTS {
            let exact = sum[l] / total;
            // f32 storage of the mean (6e-8) and the quadrature's O(1/rings²).
            assert!(
                (f64::from(w[l]) - exact).abs() < 1e-5,
                "l {l}: {} vs {exact}",
                w[l]
            );
        }
    }
}
