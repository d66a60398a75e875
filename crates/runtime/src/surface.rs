//! The surface map evaluated at a point of the original triangles: the CPU
//! reference of the fragment shader's lookup (the map's layout and why it
//! never reaches through a wall: [`radiosity_bakefile::surface`]).
//!
//! For a point `x` on triangle `t`: the voxel `v` holding `x` (the grid
//! coordinates' floor, with a neighbour tried when rounding puts `x` just
//! outside the triangle's pieces), the triangle's piece there (binary
//! search; of a piece cut by a wall, the part on `x`'s side of the cuts),
//! its patch `P`; then, in `P`'s plane, `x`'s offsets `(f_u, f_v)`
//! from the centre of `P`'s voxel along the two grid axes other than `P`'s
//! facing axis, each in `[−½, ½]`. The four patches of the quadrant are `P`
//! and its lattice neighbours at `(sign f_u, 0)`, `(0, sign f_v)` and
//! `(sign f_u, sign f_v)`, with bilinear weights `(1 − |f_u|)(1 − |f_v|)`,
//! `|f_u| (1 − |f_v|)`, `(1 − |f_u|) |f_v|`, `|f_u| |f_v|`; absent
//! neighbours drop out and the rest are renormalised. At a voxel boundary
//! both sides find the same patches with the same weights, so `H` is
//! continuous there.

use radiosity_bakefile::near_field::{bilinear, face_coords};
use radiosity_bakefile::surface::{offset_slot, voxel_key, SurfaceMap, NONE, SAMPLES_PER_PATCH};

/// Up to four (patch in matrix order, weight) pairs, weights summing to 1;
/// unused slots have weight 0.
pub type Weights = [(u32, f32); 4];

/// How a point was mapped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lookup {
    /// Through its triangle's piece in its voxel.
    Piece,
    /// Its voxel holds no piece of its triangle (rounding at a voxel
    /// boundary, or a sliver below the voxelizer's threshold): the
    /// triangle's nearest piece was used.
    NearestPiece,
    /// No patch lights this triangle.
    Unmapped,
}

/// The weights at `x` (world) on triangle `t`, and how they were found.
pub fn weights(map: &SurfaceMap, t: usize, x: [f32; 3]) -> (Weights, Lookup) {
    let none = ([(0, 0.0); 4], Lookup::Unmapped);
    if t >= map.triangles() {
        return none;
    }
    let pieces = map.pieces_of(t);
    if pieces.is_empty() {
        return none;
    }
    let g: [f64; 3] = std::array::from_fn(|k| (x[k] as f64 - map.origin[k]) / map.voxel_size);
    let v: [i64; 3] = g.map(|c| c.floor() as i64);
    let key_of = |v: [i64; 3]| -> Option<u64> {
        (0..3)
            .all(|k| v[k] >= 0 && v[k] < map.dims[k] as i64)
            .then(|| voxel_key(v.map(|c| c as u16), map.dims))
    };
    let find = |key: u64| {
        let lo = pieces.partition_point(|p| voxel_key(p.voxel, map.dims) < key);
        (lo < pieces.len() && voxel_key(pieces[lo].voxel, map.dims) == key).then_some(lo)
    };
    // Of a cut piece (a chain of parts), the part `x` lies in: along the
    // chain while `x` is not on the positive side of a part's cut.
    let first = map.tri_start[t] as usize;
    let pick = |mut i: usize| -> usize {
        let local: [f64; 3] = std::array::from_fn(|k| g[k] - pieces[i].voxel[k] as f64);
        while i + 1 < pieces.len() {
            match map.cut(first + i) {
                Some(cut) if cut.side(local) < 0.0 => i += 1,
                _ => break,
            }
        }
        i
    };
    let (piece, how) = match key_of(v).and_then(find) {
        Some(i) => (pieces[pick(i)], Lookup::Piece),
        None => {
            // The piece whose voxel centre is nearest to x.
            let best = (0..pieces.len())
                .min_by(|&a, &b| {
                    let d = |p: &radiosity_bakefile::surface::MapPiece| {
                        (0..3)
                            .map(|k| {
                                let c = p.voxel[k] as f64 + 0.5 - g[k];
                                c * c
                            })
                            .sum::<f64>()
                    };
                    d(&pieces[a]).total_cmp(&d(&pieces[b]))
                })
                .expect("pieces is not empty");
            (pieces[pick(best)], Lookup::NearestPiece)
        }
    };
    if piece.patch == NONE {
        return none;
    }
    let p = piece.patch as usize;
    let pv = map.patch_voxel[p];
    let axis = map.patch_direction[p] as usize / 2;
    let (ua, va) = ((axis + 1) % 3, (axis + 2) % 3);
    let fu = (g[ua] - (pv[ua] as f64 + 0.5)).clamp(-0.5, 0.5);
    let fv = (g[va] - (pv[va] as f64 + 0.5)).clamp(-0.5, 0.5);
    let (su, sv) = (if fu < 0.0 { -1 } else { 1 }, if fv < 0.0 { -1 } else { 1 });
    let (wu, wv) = (fu.abs(), fv.abs());
    let nb = &map.neighbours[p];
    let cand = [
        (p as u32, (1.0 - wu) * (1.0 - wv)),
        (nb[offset_slot(su, 0)], wu * (1.0 - wv)),
        (nb[offset_slot(0, sv)], (1.0 - wu) * wv),
        (nb[offset_slot(su, sv)], wu * wv),
    ];
    let total: f64 = cand.iter().filter(|c| c.0 != NONE).map(|c| c.1).sum();
    let mut out = [(0u32, 0.0f32); 4];
    let mut k = 0;
    for (q, w) in cand {
        if q != NONE && w > 0.0 {
            out[k] = (q, (w / total) as f32);
            k += 1;
        }
    }
    if k == 0 {
        out[0] = (p as u32, 1.0);
    }
    (out, how)
}

/// `Σ w · values[p]` of a weight set (three channels, `n` values each).
pub fn apply(w: &Weights, values: &[Vec<f32>; 3]) -> [f32; 3] {
    let mut h = [0.0f32; 3];
    for &(p, wt) in w {
        if wt > 0.0 {
            for c in 0..3 {
                h[c] += wt * values[c][p as usize];
            }
        }
    }
    h
}

/// Per-cell values (three channels, `n × 16`: patch `p`'s receiver cell
/// `g` at `16 p + g`, such as [`crate::Runtime::h_points`]) at `x`: each
/// patch of `w` contributes its cells' values bilinearly at `x`'s place in
/// its voxel face ([`radiosity_bakefile::near_field::bilinear`]), weighted
/// as `w` weighs the patches. The CPU reference of shade.frag's
/// `at_cells`.
pub fn at_cells(w: &Weights, map: &SurfaceMap, x: [f32; 3], values: &[Vec<f32>; 3]) -> [f32; 3] {
    let g: [f64; 3] = std::array::from_fn(|k| (x[k] as f64 - map.origin[k]) / map.voxel_size);
    let mut out = [0.0f32; 3];
    for &(p, wt) in w {
        if wt <= 0.0 {
            continue;
        }
        let p = p as usize;
        let voxel = map.patch_voxel[p].map(u32::from);
        let (u, v) = face_coords(g, voxel, map.patch_direction[p] as usize / 2);
        let base = p * SAMPLES_PER_PATCH;
        for c in 0..3 {
            out[c] += wt * bilinear(&values[c][base..base + SAMPLES_PER_PATCH], u, v);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The part of a cut piece holding the point lights it: the chain
    /// x ≥ 0.3 | x ≤ 0.6 | rest in voxel 1 maps to patches 0, 1, 2.
    #[test]
    fn a_point_takes_the_patch_of_the_part_it_lies_in() {
        let m = radiosity_bakefile::surface::cut_chain_example();
        m.check(3).unwrap();
        for (x, patch) in [
            (1.1, 0),
            (1.29, 0),
            (1.31, 1),
            (1.59, 1),
            (1.61, 2),
            (1.99, 2),
        ] {
            let (w, how) = weights(&m, 0, [x, 0.5, 0.5]);
            assert_eq!(how, Lookup::Piece);
            assert_eq!(w[0], (patch, 1.0), "x = {x}");
        }
    }
}
