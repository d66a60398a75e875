//! The CPU reference of one pair's form factor: the kernel's algorithm step
//! by step in f64 (the module doc of [`super`] gives the method), with the
//! kernel's discrete decisions taken in f32 so both paths evaluate the same
//! pairs the same way.

use super::{front_f32, hash32, rule, samples_for, ClPatch, Prepared, CERT_ATTEMPTS, R2_A1, R2_A2};
use radiosity_core::bvh::{self, Bvh, Cert};
use radiosity_core::math::{add, cross, dot, f64s, scale, sub};
use radiosity_core::patch::CORNERS;

/// A patch promoted to f64 for the reference.
#[derive(Clone, Copy)]
pub(super) struct P64 {
    pub(super) c: [f64; 3],
    pub(super) h: f64,
    pub(super) n: [f64; 3],
    pub(super) area: f64,
    pub(super) u: [f64; 3],
    pub(super) v: [f64; 3],
    pub(super) dir: u32,
    pub(super) lo: [f64; 3],
    pub(super) hi: [f64; 3],
}

impl From<&ClPatch> for P64 {
    fn from(p: &ClPatch) -> Self {
        P64 {
            c: f64s(p.c),
            h: p.h as f64,
            n: f64s(p.n),
            area: p.area as f64,
            u: f64s(p.u),
            v: f64s(p.v),
            dir: p.dir,
            lo: f64s(p.lo),
            hi: f64s(p.hi),
        }
    }
}

impl P64 {
    fn point(&self, su: f64, sv: f64) -> [f64; 3] {
        add(
            self.c,
            add(scale(self.u, self.h * su), scale(self.v, self.h * sv)),
        )
    }
    fn inside(&self, p: [f64; 3]) -> bool {
        (0..3).all(|k| self.lo[k] <= p[k] && p[k] <= self.hi[k])
    }
}

/// The receiver square relative to `x`, clipped to `n · R ≥ 0`
/// (Sutherland–Hodgman), as `clip_receiver` in the kernel.
fn clip_receiver(r: &P64, x: [f64; 3], n: [f64; 3]) -> Vec<[f64; 3]> {
    let dc = sub(r.c, x);
    let quad: [[f64; 3]; 4] =
        CORNERS.map(|(su, sv)| add(dc, add(scale(r.u, r.h * su), scale(r.v, r.h * sv))));
    let mut out = Vec::with_capacity(5);
    for i in 0..4 {
        let cur = quad[i];
        let prev = quad[(i + 3) % 4];
        let (dcur, dprev) = (dot(n, cur), dot(n, prev));
        if (dcur >= 0.0) != (dprev >= 0.0) {
            let t = dprev / (dprev - dcur);
            out.push(add(prev, scale(sub(cur, prev), t)));
        }
        if dcur >= 0.0 {
            out.push(cur);
        }
    }
    out
}

/// Lambert's contour sum `Σ γ_k n · (R_k × R_{k+1}) / |R_k × R_{k+1}|` (not
/// yet divided by 2π), as `lambert` in the kernel.
fn lambert(poly: &[[f64; 3]], n: [f64; 3]) -> f64 {
    let m = poly.len();
    let mut sum = 0.0;
    for k in 0..m {
        let (a, b) = (poly[k], poly[(k + 1) % m]);
        let c = cross(a, b);
        let cl = dot(c, c).sqrt();
        if cl > 0.0 {
            sum += cl.atan2(dot(a, b)) / cl * dot(n, c);
        }
    }
    sum
}

/// The rotation of the R2 lattice for one (emitter, receiver, sample).
pub fn lattice_offsets(e: u32, r: u32, s: u32) -> (u32, u32) {
    let seed = hash32(e ^ hash32(r ^ hash32(s)));
    (hash32(seed), hash32(seed ^ 0x9e3779b9))
}

/// Point `q` of the rotated R2 lattice in [0, 1)², exact in f32.
pub fn lattice(o: (u32, u32), q: u32) -> (f64, f64) {
    let a = o.0.wrapping_add(q.wrapping_mul(R2_A1)) >> 8;
    let b = o.1.wrapping_add(q.wrapping_mul(R2_A2)) >> 8;
    (a as f64 / 16777216.0, b as f64 / 16777216.0)
}

/// Whether triangle `leaf` (leaf order) provably blocks every segment from
/// the emitter's sample hull (`m` per side) to the receiver square, at a
/// hit the own-box rule counts. See the module doc; `certified` in the
/// kernel.
fn certified(bvh: &Bvh, leaf: u32, e: &P64, hull: f64, r: &P64, tol: f64) -> bool {
    let c: &Cert = &bvh.certs[leaf as usize];
    // The direction the own-box rule compares (none for a patch square).
    let dir = c.dir();
    let n = f64s(c.normal);
    let v: Vec<[f64; 3]> = c.v[..c.count()].iter().map(|&p| f64s(p)).collect();
    let pd = dot(n, v[0]);
    let ep = CORNERS.map(|(a, b)| e.point(a * hull, b * hull));
    let rp = CORNERS.map(|(a, b)| r.point(a, b));
    let he = ep.map(|p| dot(n, p) - pd);
    let hr = rp.map(|p| dot(n, p) - pd);
    let side = if he.iter().all(|&h| h < -tol) {
        -1.0
    } else if he.iter().all(|&h| h > tol) {
        1.0
    } else {
        return false;
    };
    if !hr.iter().all(|&h| h * side < -tol) {
        return false;
    }
    let box_side = |p: &P64, want: f64| -> bool {
        (0..8).all(|k| {
            let q = [
                if k & 1 == 0 { p.lo[0] } else { p.hi[0] },
                if k & 2 == 0 { p.lo[1] } else { p.hi[1] },
                if k & 4 == 0 { p.lo[2] } else { p.hi[2] },
            ];
            (dot(n, q) - pd) * want > tol
        })
    };
    if dir == e.dir && !box_side(e, side) {
        return false;
    }
    if dir == r.dir && !box_side(r, -side) {
        return false;
    }
    for (a, &ha) in ep.iter().zip(&he) {
        for (b, &hb) in rp.iter().zip(&hr) {
            let t = ha / (ha - hb);
            let p = add(*a, scale(sub(*b, *a), t));
            // Hits within `tol` of either patch's plane are ignored.
            if dot(sub(p, e.c), e.n) <= tol || dot(sub(p, r.c), r.n) <= tol {
                return false;
            }
            for k in 0..v.len() {
                let (p0, p1) = (v[k], v[(k + 1) % v.len()]);
                let edge = sub(p1, p0);
                if dot(cross(edge, sub(p, p0)), n) <= tol * dot(edge, edge).sqrt() {
                    return false;
                }
            }
        }
    }
    true
}

/// One unordered pair `(i, j)`, `i < j`, on the CPU: `G_ij = A_i F_ij` and
/// the info word `rule << 24 | rays cast`. The reference of `pair` in the
/// kernel: f64 arithmetic, f32 decisions.
pub fn cpu_pair(prep: &Prepared, i: usize, j: usize) -> (f64, u32) {
    let (pi, pj) = (&prep.patches[i], &prep.patches[j]);
    if !front_f32(pi, pj, prep.tol) || !front_f32(pj, pi, prep.tol) {
        return (0.0, rule::BACKFACING << 24);
    }
    let (ie, ir) = if pj.area < pi.area { (j, i) } else { (i, j) };
    let (ce, cr) = (&prep.patches[ie], &prep.patches[ir]);
    let m = samples_for(ce, cr, &prep.rules, prep.samples);
    let (e, r) = (P64::from(ce), P64::from(cr));
    let tol = prep.tol as f64;
    let mut acc = 0.0;
    let mut rays = 0u32;
    // Certificate attempts left: on each blocked ray until the first open
    // one, at most CERT_ATTEMPTS per pair.
    let mut attempts = CERT_ATTEMPTS;
    let rule_m = &prep.gauss[m as usize - 1];
    let per_sample = prep.rays.div_ceil(m * m);
    for a in 0..m {
        for b in 0..m {
            let ((su, wu), (sv, wv)) = (rule_m[a as usize], rule_m[b as usize]);
            let x = e.point(su, sv);
            if !(dot(sub(x, r.c), r.n) > 0.0) {
                continue;
            }
            let poly = clip_receiver(&r, x, e.n);
            if poly.len() < 3 {
                continue;
            }
            let offsets = lattice_offsets(ie as u32, ir as u32, a * m + b);
            let (mut kept, mut open) = (0u32, 0u32);
            let trace = |d: [f64; 3]| {
                prep.bvh.any_hit(x, d, |k, t| {
                    let tri = &prep.bvh.tris[k as usize];
                    if tri.patch == ie as u32 || tri.patch == ir as u32 {
                        return true;
                    }
                    // Same-direction exemption for scene triangles only:
                    // another patch's square is never part of e or r.
                    let scene_tri = tri.patch == bvh::SCENE;
                    let p = add(x, scale(d, t));
                    (e.inside(p)
                        && ((scene_tri && tri.dir == e.dir) || dot(sub(p, e.c), e.n) <= tol))
                        || (r.inside(p)
                            && ((scene_tri && tri.dir == r.dir) || dot(sub(p, r.c), r.n) <= tol))
                })
            };
            let cast = |d: [f64; 3], rays: &mut u32, attempts: &mut u32| -> Option<bool> {
                *rays += 1;
                match trace(d) {
                    None => {
                        *attempts = 0;
                        Some(true)
                    }
                    Some(k) if *attempts > 0 && prep.certificates => {
                        *attempts -= 1;
                        if certified(&prep.bvh, k, &e, rule_m[m as usize - 1].0, &r, tol) {
                            None
                        } else {
                            Some(false)
                        }
                    }
                    Some(_) => Some(false),
                }
            };
            for q in 0..per_sample {
                let (x1, x2) = lattice(offsets, q);
                let y = r.point(2.0 * x1 - 1.0, 2.0 * x2 - 1.0);
                let d = sub(y, x);
                if !(dot(d, e.n) > 0.0) {
                    continue;
                }
                kept += 1;
                match cast(d, &mut rays, &mut attempts) {
                    None => return (0.0, rule::BLOCKED << 24 | rays),
                    Some(true) => open += 1,
                    Some(false) => {}
                }
            }
            if kept == 0 {
                // Every lattice point lies below the horizon: one ray to the
                // clipped polygon's vertex mean instead.
                let mut d = [0.0; 3];
                for p in &poly {
                    d = add(d, *p);
                }
                let d = scale(d, 1.0 / poly.len() as f64);
                kept = 1;
                match cast(d, &mut rays, &mut attempts) {
                    None => return (0.0, rule::BLOCKED << 24 | rays),
                    Some(true) => open += 1,
                    Some(false) => {}
                }
            }
            if open == 0 {
                continue;
            }
            acc += wu * wv * lambert(&poly, e.n) * (open as f64 / kept as f64);
        }
    }
    let g = e.area * acc / (2.0 * std::f64::consts::PI);
    (g, rule::EVALUATED << 24 | rays)
}
