//! Patches of even size on cluttered models (issue 42): the patch budget
//! goes to area, not to fragments. The scene is generated
//! (`generate::build("cluttered_room")`): a 12 × 8 × 3.5 m room of
//! single-quad walls full of balusters, chairs, blocks and floating parts.
//! Before fragments were joined (module `voxelize::fragments`), 300
//! patches asked for gave 31 m voxels and no floor patch of its own, 1,000
//! gave 1.77 m voxels and a median patch of 0.004 voxel faces.

mod common;

use radiosity::bake::voxelize::{self, Resolution, Voxelization};
use radiosity::core::compute::Backend;
use radiosity::core::patch::{AreaSpread, Direction, Patch};
use radiosity::core::scene;

fn cluttered_room() -> std::path::PathBuf {
    let dir = common::temp_dir("clutter");
    let g = radiosity::generate::build("cluttered_room").unwrap();
    let written = g.write(&dir).unwrap();
    written
        .into_iter()
        .find(|p| p.extension().is_some_and(|e| e == "obj"))
        .unwrap()
}

/// Mean area of the patches `keep` selects, and how many there are.
fn mean_area(v: &Voxelization, keep: impl Fn(&Patch) -> bool) -> (f64, usize) {
    let a: Vec<f64> = v
        .patches
        .iter()
        .filter(|p| keep(p))
        .map(|p| p.area)
        .collect();
    (a.iter().sum::<f64>() / a.len().max(1) as f64, a.len())
}

/// The floor, the back wall and the side wall get patches within a factor
/// 1.5 of the even share `patch area / requested count` (above it by the
/// clutter's own patches: its fragments that share light with nothing
/// stay patches), the count is the one asked for (the search's ±5 %, with
/// margin), and the median patch is over half a voxel face.
#[test]
fn cluttered_room_floor_and_walls_get_patches_near_the_target_size() {
    let obj = cluttered_room();
    let scene = scene::load(&obj).unwrap();
    for target in [300usize, 1000] {
        let v = voxelize::voxelize(&scene, Resolution::Patches(target), &Backend::Cpu).unwrap();
        let share = v.stats.patch_area / target as f64;
        let spread = v.stats.spread;
        let what = format!(
            "{target} asked: {} patches at {:.3} m, {spread}, {} fragments joined",
            v.patches.len(),
            v.stats.voxel_size,
            v.stats.fragments_joined
        );
        println!("{what}");
        assert!(
            (v.patches.len() as f64 / target as f64 - 1.0).abs() <= 0.1,
            "{what}"
        );
        assert_eq!(
            spread,
            AreaSpread::of(v.patches.iter().map(|p| p.area), v.stats.voxel_size)
        );
        assert!(spread.p50 > 0.5, "{what}");
        // Floor patches (with the tops of the blocks standing on it: they
        // join the floor's patches as relief), the back wall (z = 8, facing
        // −z) and the side wall (x = 12, facing −x, behind nothing).
        type Select = Box<dyn Fn(&Patch) -> bool>;
        let surfaces: [(&str, Select); 3] = [
            (
                "floor",
                Box::new(|p: &Patch| p.direction == Direction::PosY && p.centre[1] < 0.2),
            ),
            (
                "back wall",
                Box::new(|p: &Patch| p.direction == Direction::NegZ && p.centre[2] > 7.99),
            ),
            (
                "side wall",
                Box::new(|p: &Patch| p.direction == Direction::NegX && p.centre[0] > 11.99),
            ),
        ];
        for (name, keep) in surfaces {
            let (mean, count) = mean_area(&v, keep);
            println!("  {name}: {count} patches of mean {mean:.3} m² (even share {share:.3} m²)");
            assert!(
                count > 1 && mean > share / 1.5 && mean < 1.5 * share,
                "{what}: {name} has {count} patches of mean {mean:.3} m², the even share is {share:.3}"
            );
        }
    }
}

/// A room whose walls, floor and ceiling are closed boxes 30 cm thick
/// (faces outwards), with blocks inside: a model whose solids have
/// insides.
fn thick_walled_room() -> std::path::PathBuf {
    let mut quads = Vec::new();
    let t = 0.3;
    let (w, h, d) = (6.0, 3.0, 5.0);
    let slabs = [
        ([-t, -t, -t], [w + t, 0.0, d + t]),
        ([-t, h, -t], [w + t, h + t, d + t]),
        ([-t, 0.0, -t], [0.0, h, d + t]),
        ([w, 0.0, -t], [w + t, h, d + t]),
        ([0.0, 0.0, -t], [w, h, 0.0]),
        ([0.0, 0.0, d], [w, h, d + t]),
    ];
    for (lo, hi) in slabs {
        quads.extend(common::block(lo, hi, [0.7; 3]));
    }
    // Shelves 2 cm thick, closed boxes.
    for k in 0..60 {
        let x = 0.3 + 0.09 * k as f64;
        let y = 0.2 + 0.04 * k as f64;
        let z = 0.3 + 0.07 * k as f64;
        quads.extend(common::block(
            [x, y, z],
            [x + 0.5, y + 0.02, z + 0.3],
            [0.5; 3],
        ));
    }
    common::write_quads("thick-walls", &quads)
}

/// `--two-sided` keeps the count asked for: a room of closed slabs 30 cm
/// thick and 60 closed shelves 2 cm thick, with back sides everywhere, half
/// of them inside solids. The voxel-size search leaves the back sides'
/// covered area out of its covered-share rule (module doc of `voxelize`):
/// a solid's insides are covered more as voxels grow, which can fail every
/// pass coarser than a fine first one, the likely cause of issue 42's
/// two-sided cathedral (2,000 asked, 18,697 made; the model is not here,
/// and on this scene the old rule did not bite either).
#[test]
fn two_sided_bakes_keep_the_patch_count_at_the_request() {
    let obj = thick_walled_room();
    let scene = scene::load(&obj).unwrap().with_back_sides();
    for target in [300usize, 1000] {
        let v = voxelize::voxelize(&scene, Resolution::Patches(target), &Backend::Cpu).unwrap();
        let what = format!(
            "two-sided, {target} asked: {} patches at {:.3} m, {}; search {:?}; covered {:.3e} \
             of which back sides {:.3e}",
            v.patches.len(),
            v.stats.voxel_size,
            v.stats.spread,
            v.stats.search,
            v.stats.covered_area,
            v.stats.covered_twin_area
        );
        println!("{what}");
        assert!(v.stats.covered_twin_area > 0.0, "{what}");
        assert!(
            (v.patches.len() as f64 / target as f64 - 1.0).abs() <= 0.1,
            "{what}"
        );
    }
}
