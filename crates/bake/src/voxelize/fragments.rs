//! Fragments: patches far smaller than a voxel face joined to a neighbour
//! whose light they share, so that a patch budget is spent on area, not
//! on clutter (issue 42).
//!
//! A cluttered model (balusters, chair legs, blocks on a floor, ornament)
//! gives, at any voxel size, many groups of a few square centimetres: each
//! side of each small object is a component of its own (module doc of
//! `voxelize`, "Connected surfaces"), because the objects separate each
//! other. Left as patches they are most of the count: the voxel-size
//! search then settles on voxels so coarse that a room's floor is two
//! patches: the generated `cluttered_room` (12 × 8 m) asked for 300
//! patches got 31 m voxels and no floor patch of its own; with fragments
//! joined it gets 1.29 m voxels, a median patch of 0.98 voxel faces and
//! floor patches 1.3 times the even share of the area.
//!
//! So after the neighbour rule, a patch smaller than [`FRAGMENT`] voxel
//! faces is joined to a patch facing the same way whose geometry lies in
//! the same or an adjacent voxel and that shares its light: each piece's
//! point is lifted off its surface into the open space in front of it (by
//! [`FRAGMENT_LIFT`] voxels, or half the distance to the first surface in
//! front when that is nearer, so a lifted point never passes through
//! anything), and open space must join the two lifted points: the segment
//! between them crosses no surface at all, or a detour of the same length
//! sideways (along an axis of the patches' plane: out of the gaps of a
//! railing, around a chair leg) does. A wall, floor or slab between them
//! blocks, so a fragment never joins a patch in another room and no leak
//! returns; two baluster sides facing the same way, or two blocks' sides
//! on one floor, join. Of the patches that qualify, the nearest (closest
//! pair of pieces) wins. A piece with a surface right in front has no
//! open space and joins through none of its points.
//!
//! Bounds keep the result a patch: a fragment joins a patch of at least
//! [`FRAGMENT`] voxel faces freely (it adds little), another fragment only
//! while their union stays within one voxel face, and no patch grows
//! beyond [`FRAGMENT_SPAN`] voxels along any axis. Fragments are taken
//! smallest first, in a fixed order, so the result is deterministic.
//! What is joined is counted (`VoxelStats::fragments_joined`); fragments
//! with nothing to join (an object alone in a voxel neighbourhood) stay
//! patches.

use radiosity_core::bvh::Bvh;
use radiosity_core::patch::{Direction, Grid};
use rayon::prelude::*;
use std::collections::HashMap;

/// Patches smaller than this many voxel faces are fragments.
pub const FRAGMENT: f64 = 0.25;

/// How far a piece's point is lifted into the open space in front of it
/// for the fragment test, in voxel sizes (the relief lift of `voxelize`).
pub const FRAGMENT_LIFT: f64 = 0.25;

/// The most voxels a patch made of joined fragments spans along any axis
/// (a voxel and its neighbours).
pub const FRAGMENT_SPAN: u32 = 3;

/// Pairs of pieces (closest first) tested between a fragment and each
/// candidate patch.
const PAIRS: usize = 4;

/// A patch before fragments are joined: its direction, the voxels its
/// pieces lie in, its area (scene units², from the host's coordinates, so
/// that the OpenCL and CPU pieces give the same decisions) and its pieces'
/// points and unit normals (world coordinates).
pub struct Group {
    pub dir: Direction,
    pub voxels: Vec<[u32; 3]>,
    pub area: f64,
    pub members: Vec<([f64; 3], [f64; 3])>,
}

/// For each group, the group it ends in (itself when it is kept as it is),
/// and how many groups were joined to another.
pub fn join(groups: &[Group], grid: &Grid, bvh: &Bvh) -> (Vec<usize>, u64) {
    let s2 = grid.size * grid.size;
    let n = groups.len();
    let mut owner: Vec<usize> = (0..n).collect();
    let fragments: Vec<usize> = {
        let mut f: Vec<usize> = (0..n).filter(|&g| groups[g].area < FRAGMENT * s2).collect();
        f.sort_by(|&a, &b| groups[a].area.total_cmp(&groups[b].area).then(a.cmp(&b)));
        f
    };
    if fragments.is_empty() {
        return (owner, 0);
    }
    // Each piece's point lifted into the open space in front of it.
    // BVH coordinates are world coordinates minus the grid's centre (the
    // shift the voxelizer builds its BVH with).
    let shift = grid.centre();
    let lift = FRAGMENT_LIFT * grid.size;
    let start = super::CONNECT_LIFT * grid.size;
    // A piece with a surface right in front of it (nearer than the start
    // lift) has no open space to lift into and joins nothing through that
    // point (`None`). Pieces lying on another surface whose front sees
    // nothing of the scene (a block's bottom on a closed room's floor) are
    // covered (`cover`): lifted, their points were under the floor, where
    // a segment passed beneath a wall.
    let lifted: Vec<Vec<Option<[f64; 3]>>> = groups
        .par_iter()
        .map(|g| {
            g.members
                .iter()
                .map(|&(p, nrm)| {
                    let o: [f64; 3] = std::array::from_fn(|k| p[k] + start * nrm[k] - shift[k]);
                    let d = nrm.map(|c| c * lift);
                    let h = match bvh.closest_hit(o, d) {
                        Some((_, t)) if t * lift <= start => return None,
                        Some((_, t)) => start + 0.5 * t * lift,
                        None => start + lift,
                    };
                    Some(std::array::from_fn(|k| p[k] + h * nrm[k]))
                })
                .collect()
        })
        .collect();
    // Which groups have pieces in each (voxel, direction).
    let mut at: HashMap<(u64, Direction), Vec<usize>> = HashMap::new();
    for (g, group) in groups.iter().enumerate() {
        for &v in &group.voxels {
            let e = at.entry((grid.key(v), group.dir)).or_default();
            if e.last() != Some(&g) {
                e.push(g);
            }
        }
    }
    // Per root: its area, its groups, and the box of its voxels.
    let mut area: Vec<f64> = groups.iter().map(|g| g.area).collect();
    let mut parts: Vec<Vec<usize>> = (0..n).map(|g| vec![g]).collect();
    let mut bounds: Vec<([u32; 3], [u32; 3])> = groups
        .iter()
        .map(|g| {
            let mut lo = [u32::MAX; 3];
            let mut hi = [0u32; 3];
            for v in &g.voxels {
                for k in 0..3 {
                    lo[k] = lo[k].min(v[k]);
                    hi[k] = hi[k].max(v[k]);
                }
            }
            (lo, hi)
        })
        .collect();
    fn root(owner: &mut [usize], mut x: usize) -> usize {
        while owner[x] != x {
            owner[x] = owner[owner[x]];
            x = owner[x];
        }
        x
    }
    let clear = |a: [f64; 3], b: [f64; 3]| -> bool {
        let o: [f64; 3] = std::array::from_fn(|k| a[k] - shift[k]);
        let d: [f64; 3] = std::array::from_fn(|k| b[k] - a[k]);
        bvh.any_hit(o, d, |_, _| false).is_none()
    };
    // Open space joins the two lifted points: the segment between them
    // is clear, or a detour [`FRAGMENT_LIFT`] voxels sideways along an axis
    // of the patches' plane is (the sides of balusters in a row face each
    // other's gaps, which open on the railing's front).
    let detour = lift;
    let open_path = |a: [f64; 3], b: [f64; 3], dir: Direction| -> bool {
        if clear(a, b) {
            return true;
        }
        (0..3).filter(|&k| k != dir.axis()).any(|k| {
            [-detour, detour].into_iter().any(|t| {
                let (mut a2, mut b2) = (a, b);
                a2[k] += t;
                b2[k] += t;
                clear(a, a2) && clear(a2, b2) && clear(b2, b)
            })
        })
    };
    let mut joined = 0u64;
    for &f in &fragments {
        let r = root(&mut owner, f);
        if area[r] >= FRAGMENT * s2 {
            continue;
        }
        let dir = groups[f].dir;
        // Candidate roots: groups facing `dir` in the voxels around any of
        // the fragment's.
        let mut cands: Vec<usize> = Vec::new();
        for &g in &parts[r] {
            for v in &groups[g].voxels {
                for dz in -1i64..=1 {
                    for dy in -1i64..=1 {
                        for dx in -1i64..=1 {
                            let c = [v[0] as i64 + dx, v[1] as i64 + dy, v[2] as i64 + dz];
                            if (0..3).any(|k| c[k] < 0 || c[k] >= grid.dims[k] as i64) {
                                continue;
                            }
                            let nb = [c[0] as u32, c[1] as u32, c[2] as u32];
                            if let Some(list) = at.get(&(grid.key(nb), dir)) {
                                cands.extend(list.iter().copied());
                            }
                        }
                    }
                }
            }
        }
        let mut roots: Vec<usize> = cands.into_iter().map(|c| root(&mut owner, c)).collect();
        roots.sort_unstable();
        roots.dedup();
        let mut best: Option<(f64, usize)> = None;
        for &c in &roots {
            if c == r {
                continue;
            }
            if area[c] < FRAGMENT * s2 && area[c] + area[r] > s2 {
                continue;
            }
            let (lo, hi) = (bounds[r], bounds[c]);
            if (0..3).any(|k| hi.1[k].max(lo.1[k]) - hi.0[k].min(lo.0[k]) >= FRAGMENT_SPAN) {
                continue;
            }
            // The PAIRS closest pairs of pieces with open space in front
            // (kept sorted while scanning: no list of every pair), tested
            // until one is joined through it.
            type Pair = (f64, usize, usize, usize, usize);
            let before = |a: &Pair, b: &Pair| {
                a.0.total_cmp(&b.0)
                    .then((a.1, a.2, a.3, a.4).cmp(&(b.1, b.2, b.3, b.4)))
                    .is_lt()
            };
            let mut pairs: Vec<Pair> = Vec::with_capacity(PAIRS + 1);
            for &g in &parts[r] {
                for (i, p) in groups[g].members.iter().enumerate() {
                    if lifted[g][i].is_none() {
                        continue;
                    }
                    for &h in &parts[c] {
                        for (j, q) in groups[h].members.iter().enumerate() {
                            if lifted[h][j].is_none() {
                                continue;
                            }
                            let d = radiosity_core::math::norm(radiosity_core::math::sub(p.0, q.0));
                            let pair = (d, g, i, h, j);
                            if pairs.len() == PAIRS && !before(&pair, &pairs[PAIRS - 1]) {
                                continue;
                            }
                            let at = pairs.partition_point(|x| before(x, &pair));
                            pairs.insert(at, pair);
                            pairs.truncate(PAIRS);
                        }
                    }
                }
            }
            let near = pairs.first().map_or(f64::INFINITY, |p| p.0);
            if best.is_some_and(|(d, _)| d <= near) {
                continue;
            }
            if pairs
                .iter()
                .take(PAIRS)
                .filter_map(|&(_, g, i, h, j)| lifted[g][i].zip(lifted[h][j]))
                .any(|(a, b)| open_path(a, b, dir))
            {
                best = Some((near, c));
            }
        }
        if let Some((_, c)) = best {
            owner[r] = c;
            area[c] += area[r];
            let moved = std::mem::take(&mut parts[r]);
            parts[c].extend(moved);
            let (a, b) = (bounds[r], bounds[c]);
            bounds[c] = (
                std::array::from_fn(|k| a.0[k].min(b.0[k])),
                std::array::from_fn(|k| a.1[k].max(b.1[k])),
            );
            joined += 1;
        }
    }
    let ends = (0..n).map(|g| root(&mut owner, g)).collect();
    (ends, joined)
}
