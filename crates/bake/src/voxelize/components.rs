//! The reduction's connectivity phase (module doc of [`super`],
//! "Connected surfaces"): the pieces of one voxel facing one way, split
//! where a surface separates them. A piece joins every component holding
//! one of its [`NEAREST`] nearest pieces that it is connected to (so chains
//! of pieces along a curved or bumpy surface stay one component); small
//! components (relief) then join the nearest component they reach over a
//! lift of [`RELIEF_LIFT`] voxels.

use super::groups::{Acc, Geometry, Kept};
use super::visibility::Visible;
use super::{Piece, VoxelStats, NEAREST, RELIEF_LIFT, SMALL_COMPONENT};
use radiosity_core::math::sub;
use radiosity_core::patch::Direction;
use std::collections::HashMap;

/// One connected part of the pieces of a voxel facing one way.
pub(super) struct Comp {
    pub(super) key: u64,
    pub(super) dir: Direction,
    pub(super) voxel: [u32; 3],
    /// Index among the components of its (voxel, direction).
    pub(super) local: u32,
    pub(super) acc: Acc,
    /// Its pieces' centroids (a visible point where part of one is covered)
    /// and normals.
    pub(super) members: Vec<([f64; 3], [f64; 3])>,
    /// Its visible area from the host's coordinates (module
    /// `fragments`: the same on every backend).
    pub(super) host_area: f64,
}

/// Every component, where to find them, and each visible piece's.
pub(super) struct Components {
    pub(super) comps: Vec<Comp>,
    /// The components of each (voxel key, direction).
    pub(super) at: HashMap<(u64, Direction), Vec<usize>>,
    /// Per visible piece (in [`Visible::kept`]'s order): its component.
    pub(super) of_kept: Vec<usize>,
}

/// Splits the visible pieces (`vis`, sorted by voxel and direction) into
/// components, counting the split groups in `stats`.
pub(super) fn split(
    g: &Geometry,
    pieces: &[Piece],
    vis: &Visible,
    stats: &mut VoxelStats,
) -> Components {
    let (grid, bvh, normals, lift, own) = (g.grid, g.bvh, g.normals, g.lift, g.own);
    let s2 = grid.size * grid.size;
    let kept: &[Kept] = &vis.kept;
    let mut comps: Vec<Comp> = Vec::new();
    let mut comps_at: HashMap<(u64, Direction), Vec<usize>> = HashMap::new();
    let mut comp_of_kept = vec![0usize; kept.len()];
    let mut a = 0usize;
    while a < kept.len() {
        let (key, dir) = (kept[a].0, kept[a].1);
        let mut b = a;
        while b < kept.len() && (kept[b].0, kept[b].1) == (key, dir) {
            b += 1;
        }
        let run: Vec<(Acc, [f64; 3], [f64; 3])> = (a..b)
            .map(|idx| {
                let (_, _, tri, i) = kept[idx];
                let acc = Acc::of_piece(g, &pieces[i], tri, vis.share[idx]);
                (acc, vis.point[idx], normals[tri as usize])
            })
            .collect();
        // Union-find over the run.
        let mut parent: Vec<usize> = (0..run.len()).collect();
        fn root(parent: &mut [usize], mut x: usize) -> usize {
            while parent[x] != x {
                parent[x] = parent[parent[x]];
                x = parent[x];
            }
            x
        }
        for p in 1..run.len() {
            let mut near: Vec<(f64, usize)> = (0..p)
                .map(|q| (radiosity_core::math::norm(sub(run[p].1, run[q].1)), q))
                .collect();
            near.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
            for &(_, q) in near.iter().take(NEAREST) {
                let (rp, rq) = (root(&mut parent, p), root(&mut parent, q));
                if rp == rq {
                    continue;
                }
                if bvh.surface_segment_clear(
                    run[q].1, run[q].2, run[p].1, run[p].2, lift, own, dir as u32,
                ) {
                    parent[rp.max(rq)] = rp.min(rq);
                }
            }
        }
        // Small components (relief: the faces of a moulding's steps, bits
        // of ornament) join the nearest component they reach over a lift of
        // RELIEF_LIFT voxels: relief lower than that does not separate, a
        // wall or a floor above does.
        let areas: Vec<f64> = {
            let mut s = vec![0.0; run.len()];
            for (k, piece) in run.iter().enumerate() {
                let r = root(&mut parent, k);
                s[r] += piece.0.area;
            }
            s
        };
        let small = SMALL_COMPONENT * s2;
        for p in 0..run.len() {
            let rp = root(&mut parent, p);
            if areas[rp] >= small {
                continue;
            }
            let mut near: Vec<(f64, usize)> = (0..run.len())
                .filter(|&q| root(&mut parent, q) != rp)
                .map(|q| (radiosity_core::math::norm(sub(run[p].1, run[q].1)), q))
                .collect();
            near.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
            for &(_, q) in near.iter().take(NEAREST) {
                let (rp, rq) = (root(&mut parent, p), root(&mut parent, q));
                if rp != rq
                    && bvh.surface_segment_clear(
                        run[q].1,
                        run[q].2,
                        run[p].1,
                        run[p].2,
                        RELIEF_LIFT * grid.size,
                        own,
                        dir as u32,
                    )
                {
                    parent[rp.max(rq)] = rp.min(rq);
                    break;
                }
            }
        }
        let first = comps.len();
        let mut comp_of_root: HashMap<usize, usize> = HashMap::new();
        for (k, piece) in run.iter().enumerate() {
            let r = root(&mut parent, k);
            let c = *comp_of_root.entry(r).or_insert_with(|| {
                comps.push(Comp {
                    key,
                    dir,
                    voxel: pieces[kept[a + k].3].voxel,
                    local: (comps.len() - first) as u32,
                    acc: Acc::default(),
                    members: Vec::new(),
                    host_area: 0.0,
                });
                comps_at
                    .entry((key, dir))
                    .or_default()
                    .push(comps.len() - 1);
                comps.len() - 1
            });
            comps[c].acc.add(&piece.0);
            comps[c].members.push((piece.1, piece.2));
            comps[c].host_area += vis.host_area[a + k];
            comp_of_kept[a + k] = c;
        }
        stats.split_groups += (comps.len() - first - 1) as u64;
        a = b;
    }
    Components {
        comps,
        at: comps_at,
        of_kept: comp_of_kept,
    }
}

/// Whether two components facing one way are connected: their [`NEAREST`]
/// closest pairs of pieces, tested until one is.
pub(super) fn connected(g: &Geometry, x: &Comp, y: &Comp) -> bool {
    let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
    for (i, p) in x.members.iter().enumerate() {
        for (j, q) in y.members.iter().enumerate() {
            pairs.push((radiosity_core::math::norm(sub(p.0, q.0)), i, j));
        }
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then((a.1, a.2).cmp(&(b.1, b.2))));
    pairs.iter().take(NEAREST).any(|&(_, i, j)| {
        let (p, q) = (x.members[i], y.members[j]);
        g.bvh
            .surface_segment_clear(p.0, p.1, q.0, q.1, g.lift, g.own, x.dir as u32)
    })
}
