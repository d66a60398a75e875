//! The patch preview (`bake --export`'s `patches.png`) draws each patch as
//! its real region: on a large untessellated plate at an angle to the grid,
//! the drawn pixels are exactly the plate's, where squares of the patches'
//! areas stick out past its edges and leave gaps.

mod common;

use common::{quad, write_quads};
use radiosity::bake::pieces::{self, PieceGeo};
use radiosity::bake::preview::{render_pieces, UNOWNED};
use radiosity::bake::voxelize::voxelize_at;
use radiosity::core::compute::Backend;
use radiosity::core::math::{cross, normalize};
use radiosity::core::scene;
use radiosity::core::scene_config::Camera;

const BACKGROUND: [u8; 3] = [24, 24, 32];

#[test]
fn the_preview_draws_each_patch_as_its_real_region() {
    // A 2 × 1.3 plate tilted about two axes, one quad, and a voxel size
    // (0.17) that divides nothing: slivers along every edge.
    let n = normalize([0.3, 0.2, 1.0]);
    let u = normalize(cross([0.0, 1.0, 0.0], n));
    let v = cross(n, u);
    let path = write_quads(
        "preview",
        &[quad([0.1, 0.05, 0.0], u, v, 1.0, 0.65, [0.8; 3])],
    );
    let scene = scene::load(&path).unwrap();
    let vox = voxelize_at(&scene, 0.17, &Backend::Cpu).unwrap();
    assert!(vox.patches.len() > 50, "{} patches", vox.patches.len());
    let geo = pieces::geometry(&scene, &vox);
    let owner: Vec<Option<u32>> = vox.pieces.iter().map(|p| p.patch).collect();
    let camera = Camera {
        position: [0.6, 0.4, 3.0],
        target: [0.1, 0.05, 0.0],
        up: [0.0, 1.0, 0.0],
        fov_y_deg: 60.0,
    };
    let (w, h) = (320, 240);
    let img = render_pieces(&geo, &owner, &vox.patches, &camera, w, h);

    // The plate itself, as one piece per triangle, drawn the same way.
    let tris: Vec<PieceGeo> = scene
        .triangles
        .iter()
        .enumerate()
        .map(|(t, tri)| {
            let poly: Vec<[f64; 3]> = tri
                .iter()
                .map(|&i| scene.positions[i as usize].map(|x| x as f64))
                .collect();
            let normal = scene.triangle_normal(t);
            let (area, centroid) = pieces::polygon_area_centroid(&poly, normal);
            PieceGeo {
                poly,
                normal,
                area,
                centroid,
            }
        })
        .collect();
    let plate = render_pieces(
        &tris,
        &vec![Some(0); tris.len()],
        &vox.patches[..1],
        &camera,
        w,
        h,
    );
    let drawn = |img: &image::RgbImage, x: u32, y: u32| img.get_pixel(x, y).0 != BACKGROUND;
    let (mut inside, mut differ, mut unowned) = (0u32, 0u32, 0u32);
    for y in 0..h {
        for x in 0..w {
            inside += u32::from(drawn(&plate, x, y));
            differ += u32::from(drawn(&plate, x, y) != drawn(&img, x, y));
            unowned += u32::from(img.get_pixel(x, y).0 == UNOWNED);
        }
    }
    assert!(inside > 10_000, "the plate covers {inside} pixels");
    // The pieces tile the plate exactly; a pixel centre lying on an edge
    // shared by two pieces may be claimed by neither (the fill rule has no
    // tie-break), which the bound allows for a handful of pixels.
    assert!(
        differ * 1000 <= inside,
        "{differ} of {inside} pixels differ from the plate's"
    );
    assert_eq!(unowned, 0, "every piece of the plate has a patch");
}
