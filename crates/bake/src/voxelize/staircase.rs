//! The reduction's neighbour rule (module doc of [`super`], "Neighbour
//! rule"): a component continues into the neighbour voxel along its
//! direction when a component there facing the same way is connected to it
//! (a staircase of voxels along a tilted or curved surface); the chain's
//! last component is the patch. A component whose neighbour holds a
//! surface looking back stays a patch, counted.

use super::components::{connected, Components};
use super::groups::Geometry;
use super::VoxelStats;
use std::collections::HashMap;

/// Per component, the component its chain ends in (itself when its
/// neighbour voxel does not continue it). `holds`: the directions each
/// occupied voxel holds, by key (bit `d`).
pub(super) fn chain_ends(
    g: &Geometry,
    c: &Components,
    holds: &HashMap<u64, u8>,
    stats: &mut VoxelStats,
) -> Vec<usize> {
    let (grid, comps, comps_at) = (g.grid, &c.comps, &c.at);
    let mut target: Vec<usize> = (0..comps.len()).collect();
    let mut resolved = vec![false; comps.len()];
    for c in 0..comps.len() {
        let mut chain = vec![c];
        let mut at = c;
        loop {
            if resolved[at] {
                at = target[at];
                break;
            }
            let Some(nb) = grid.neighbour(comps[at].voxel, comps[at].dir) else {
                break;
            };
            let next = comps_at
                .get(&(grid.key(nb), comps[at].dir))
                .and_then(|cands| {
                    cands
                        .iter()
                        .copied()
                        .find(|&k| connected(g, &comps[at], &comps[k]))
                });
            match next {
                Some(k) => {
                    chain.push(k);
                    at = k;
                }
                None => {
                    let back = 1u8 << comps[at].dir.opposite() as u8;
                    if holds.get(&grid.key(nb)).is_some_and(|m| m & back != 0) {
                        // A surface looks back from less than two voxels
                        // away (a column, a thin wall's other side, a box
                        // on the floor): the component still receives and
                        // reflects light, so it stays a patch, counted.
                        stats.facing_back_groups += 1;
                    }
                    break;
                }
            }
        }
        for &k in &chain {
            target[k] = at;
            resolved[k] = true;
        }
    }
    target
}
