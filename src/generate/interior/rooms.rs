//! What stands in the interior's rooms (the module doc of [`super`]): the
//! hall with its arcade, mezzanine and stair, the living room, the bedroom
//! and the dining room, each built into the shared [`Interior`] from its
//! walls' frame.

use super::{
    arch_radius, spring, stair_foot_z, Facing, Frame, Interior, ARCADE_X, ARCADE_Z, BAYS, HALL_H,
    MAX_CELL, MEZZ_BOTTOM, MEZZ_FRONT, MEZZ_TOP, PIER_HALF, ROOM_H, STAIR_RISE, STAIR_RISERS,
    STAIR_RUN, STAIR_X,
};
use crate::generate::mesh::{ALL, NX, NY, NZ, PX, PY, PZ};
use glam::DVec3;

/// The hall: its room surfaces, the mezzanine, the arcade, the stair, the
/// railings and its furniture (below and on the mezzanine).
pub(super) fn hall(s: &mut Interior) {
    let (x0, x1, z0, z1) = (0.2, 9.9, 0.2, 7.9);
    let sp = spring();
    let foot = stair_foot_z();
    // Furniture on the hall floor.
    let (walnut, pine, red, blue, linen) = (
        s.m.walnut,
        s.m.pine,
        s.m.fabric_red,
        s.m.fabric_blue,
        s.m.linen,
    );
    s.bookcase(
        &Frame::fit(4.3, z0, 0.0, 1.4, 0.35, Facing::S),
        1.4,
        2.4,
        0.35,
        6,
    );
    s.bookcase(
        &Frame::fit(7.9, z0, 0.0, 1.6, 0.35, Facing::S),
        1.6,
        2.4,
        0.35,
        6,
    );
    s.table(
        &Frame::fit(4.3, 1.3, 0.0, 1.6, 0.8, Facing::S),
        1.6,
        0.8,
        0.75,
        pine,
    );
    for x in [4.5, 5.25] {
        s.chair(
            &Frame::fit(x, 0.82, 0.0, 0.44, 0.44, Facing::S),
            walnut,
            linen,
        );
        s.chair(
            &Frame::fit(x + 0.1, 2.14, 0.0, 0.44, 0.44, Facing::N),
            walnut,
            linen,
        );
    }
    s.rug((4.9, 7.5), (4.3, 6.1));
    s.sofa(&Frame::fit(5.0, 6.2, 0.0, 2.4, 0.9, Facing::N), 2.4, red);
    s.sofa(
        &Frame::fit(3.9, 4.75, 0.0, 0.95, 0.9, Facing::E),
        0.95,
        blue,
    );
    s.sofa(
        &Frame::fit(7.6, 4.75, 0.0, 0.95, 0.9, Facing::W),
        0.95,
        blue,
    );
    s.round_table(6.2, 5.2, 0.012, 0.45, 0.42);
    s.cabinet(
        &Frame::fit(9.45, 6.0, 0.0, 1.6, 0.45, Facing::W),
        1.6,
        0.45,
        0.85,
        3,
        walnut,
        pine,
    );
    let mut floor_cuts = s.take_cuts();
    floor_cuts.push([STAIR_X.0, STAIR_X.1, MEZZ_FRONT, foot]);
    floor_cuts.push([x0, ARCADE_X.0 + PIER_HALF, ARCADE_Z.0, ARCADE_Z.1]);
    floor_cuts.push([ARCADE_X.1 - PIER_HALF, x1, ARCADE_Z.0, ARCADE_Z.1]);

    // Wall areas hidden by the slab, the arcade's ends and the stair.
    let slab_ns = [x0, x1, MEZZ_BOTTOM, MEZZ_TOP];
    let slab_we = [z0, MEZZ_FRONT, MEZZ_BOTTOM, MEZZ_TOP];
    let arcade_end = [ARCADE_Z.0, ARCADE_Z.1, 0.0, MEZZ_BOTTOM];
    let mut west = vec![slab_we, arcade_end];
    for i in 1..STAIR_RISERS {
        let z_hi = foot - STAIR_RUN * (i - 1) as f64;
        west.push([z_hi - STAIR_RUN, z_hi, 0.0, STAIR_RISE * i as f64]);
    }
    let plaster = s.m.plaster;
    let stone_floor = s.m.stone_floor;
    s.room(
        (x0, x1),
        (z0, z1),
        HALL_H,
        plaster,
        stone_floor,
        [&west, &[slab_we, arcade_end], &[slab_ns], &[]],
        &floor_cuts,
        &[],
    );

    // The mezzanine slab: oak floor on top, plastered underside and edge.
    let ceiling = s.m.ceiling;
    s.mat(ceiling);
    s.b.plane_rect(1, MEZZ_BOTTOM, -1.0, (x0, x1), (z0, ARCADE_Z.0));
    s.mat(plaster);
    s.b.plane_rect(2, MEZZ_FRONT, 1.0, (STAIR_X.1, x1), (MEZZ_BOTTOM, MEZZ_TOP));

    // The arcade: four arched bays between the stair's pier and the east
    // wall, carried by three columns and two pilasters.
    let stone = s.m.stone;
    s.mat(stone);
    let bay = (ARCADE_X.1 - ARCADE_X.0) / BAYS as f64;
    let r = arch_radius();
    let depth = ARCADE_Z.1 - ARCADE_Z.0;
    for k in 0..BAYS {
        let a0 = ARCADE_X.0 + bay * k as f64;
        let arch = crate::generate::mesh::Arch::new(
            a0,
            a0 + bay,
            sp,
            MEZZ_BOTTOM,
            a0 + bay / 2.0,
            r,
            MAX_CELL,
        );
        s.b.arch_face(
            &arch,
            DVec3::new(0.0, 0.0, ARCADE_Z.1),
            DVec3::X,
            DVec3::Y,
            DVec3::Z,
        );
        s.b.arch_face(
            &arch,
            DVec3::new(0.0, 0.0, ARCADE_Z.0),
            DVec3::X,
            DVec3::Y,
            -DVec3::Z,
        );
        s.b.arch_intrados(
            &arch,
            DVec3::new(0.0, 0.0, ARCADE_Z.0),
            DVec3::X,
            DVec3::Y,
            DVec3::Z * depth,
        );
    }
    let zc = 0.5 * (ARCADE_Z.0 + ARCADE_Z.1);
    for k in 1..BAYS {
        let xc = ARCADE_X.0 + bay * k as f64;
        // Capital: as deep as the arcade wall, carrying the masonry
        // between two arches; its top is hidden under the wall.
        s.b.axis_box(
            DVec3::new(xc - PIER_HALF, sp - 0.2, ARCADE_Z.0),
            DVec3::new(xc + PIER_HALF, sp, ARCADE_Z.1),
            ALL & !PY,
        );
        // Plinth and shaft.
        s.b.axis_box(
            DVec3::new(xc - 0.22, 0.0, zc - 0.22),
            DVec3::new(xc + 0.22, 0.15, zc + 0.22),
            ALL & !NY,
        );
        s.b.cylinder(
            DVec3::new(xc, 0.15, zc),
            depth / 2.0,
            sp - 0.2 - 0.15,
            24,
            (false, false),
        );
    }
    // Pilasters at both ends and the pier beside the stair (up to the slab).
    s.b.axis_box(
        DVec3::new(ARCADE_X.0, 0.0, ARCADE_Z.0),
        DVec3::new(ARCADE_X.0 + PIER_HALF, sp, ARCADE_Z.1),
        PX | NZ | PZ,
    );
    s.b.axis_box(
        DVec3::new(ARCADE_X.1 - PIER_HALF, 0.0, ARCADE_Z.0),
        DVec3::new(ARCADE_X.1, sp, ARCADE_Z.1),
        NX | NZ | PZ,
    );
    s.b.plane_rect(2, ARCADE_Z.0, -1.0, (x0, ARCADE_X.0), (0.0, MEZZ_BOTTOM));
    s.b.plane_rect(
        2,
        ARCADE_Z.1,
        1.0,
        (STAIR_X.1, ARCADE_X.0),
        (0.0, MEZZ_BOTTOM),
    );

    // The stair, against the west wall; its east side is open.
    s.b.stairs(
        DVec3::new(STAIR_X.0, 0.0, foot),
        -DVec3::Z,
        DVec3::X,
        STAIR_RISERS,
        STAIR_RISE,
        STAIR_RUN,
        STAIR_X.1 - STAIR_X.0,
        (false, true),
    );

    // Railings: the mezzanine's front edge and the stair's open side.
    let metal = s.m.metal;
    s.mat(metal);
    let (rz0, rz1) = (3.1, 3.16);
    let rail_x0 = STAIR_X.1;
    s.b.axis_box(
        DVec3::new(rail_x0, MEZZ_TOP + 0.95, rz0 - 0.01),
        DVec3::new(x1, MEZZ_TOP + 1.0, rz1 + 0.01),
        ALL & !PX,
    );
    s.b.axis_box(
        DVec3::new(rail_x0, MEZZ_TOP + 0.05, rz0),
        DVec3::new(x1, MEZZ_TOP + 0.1, rz1),
        ALL & !PX,
    );
    let n = ((x1 - rail_x0) / 0.125).round() as usize;
    for i in 0..n {
        let x = rail_x0 + (x1 - rail_x0) * (i as f64 + 0.5) / n as f64;
        let (lo_y, hi_y) = (MEZZ_TOP + 0.1, MEZZ_TOP + 0.95);
        s.b.axis_box(
            DVec3::new(x - 0.0125, lo_y, 3.1175),
            DVec3::new(x + 0.0125, hi_y, 3.1425),
            NX | PX | NZ | PZ,
        );
    }
    // Stair handrail: a sloped bar 0.9 m above the nosing line, with posts.
    let slope = STAIR_RISE / STAIR_RUN;
    let nosing = |z: f64| (foot - z) * slope;
    let (za, zb) = (foot - 0.15, MEZZ_FRONT + 0.05);
    let xr = STAIR_X.1 - 0.03;
    let pa = DVec3::new(xr, nosing(za) + 0.9, za);
    let pb = DVec3::new(xr, nosing(zb) + 0.9, zb);
    let along = (pb - pa) * 0.5;
    let normal = DVec3::new(0.0, along.z, -along.y).normalize() * 0.025;
    s.b.oriented_box((pa + pb) * 0.5, [along, DVec3::X * 0.025, normal], ALL);
    for i in [2usize, 7, 12, 17] {
        let z_mid = foot - STAIR_RUN * (i as f64 - 0.5);
        let y_tread = STAIR_RISE * i as f64;
        let top = nosing(z_mid) + 0.9 - 0.03;
        s.b.axis_box(
            DVec3::new(xr - 0.02, y_tread, z_mid - 0.02),
            DVec3::new(xr + 0.02, top, z_mid + 0.02),
            NX | PX | NZ | PZ,
        );
    }

    // On the mezzanine: a desk, a chair, two bookcases and a daybed.
    s.table(
        &Frame::fit(5.2, 0.6, MEZZ_TOP, 1.6, 0.75, Facing::S),
        1.6,
        0.75,
        0.75,
        walnut,
    );
    s.chair(
        &Frame::fit(5.75, 1.45, MEZZ_TOP, 0.44, 0.44, Facing::N),
        walnut,
        red,
    );
    s.bookcase(
        &Frame::fit(8.0, z0, MEZZ_TOP, 1.6, 0.35, Facing::S),
        1.6,
        2.2,
        0.35,
        5,
    );
    s.bookcase(
        &Frame::fit(0.5, z0, MEZZ_TOP, 1.8, 0.35, Facing::S),
        1.8,
        2.2,
        0.35,
        5,
    );
    s.sofa(
        &Frame::fit(9.0, 1.0, MEZZ_TOP, 1.9, 0.9, Facing::W),
        1.9,
        blue,
    );
    let cuts = s.take_cuts();
    let oak = s.m.oak;
    s.mat(oak);
    s.wall(1, MEZZ_TOP, 1.0, (x0, x1), (z0, MEZZ_FRONT), &cuts);
}

/// The living room: sofa, armchair, coffee table, rug, two bookcases, a
/// low sideboard under the north window and an emissive ceiling lamp.
pub(super) fn living(s: &mut Interior) {
    let (walnut, pine, red, blue, oak, plaster) = (
        s.m.walnut,
        s.m.pine,
        s.m.fabric_red,
        s.m.fabric_blue,
        s.m.oak,
        s.m.plaster,
    );
    s.rug((11.9, 14.5), (2.2, 4.2));
    s.sofa(&Frame::fit(12.0, 4.3, 0.0, 2.4, 0.9, Facing::N), 2.4, red);
    s.sofa(
        &Frame::fit(10.8, 2.5, 0.0, 0.95, 0.9, Facing::E),
        0.95,
        blue,
    );
    s.table(
        &Frame::fit(12.6, 2.9, 0.012, 1.2, 0.6, Facing::S),
        1.2,
        0.6,
        0.42,
        walnut,
    );
    s.bookcase(
        &Frame::fit(10.1, 0.6, 0.0, 1.6, 0.35, Facing::E),
        1.6,
        2.2,
        0.35,
        5,
    );
    s.bookcase(
        &Frame::fit(17.45, 4.7, 0.0, 1.1, 0.35, Facing::W),
        1.1,
        2.2,
        0.35,
        5,
    );
    s.cabinet(
        &Frame::fit(11.6, 0.2, 0.0, 1.8, 0.45, Facing::S),
        1.8,
        0.45,
        0.55,
        3,
        walnut,
        pine,
    );
    let lamp = s.lamp(13.2, 3.2, ROOM_H);
    let cuts = s.take_cuts();
    s.room(
        (10.1, 17.8),
        (0.2, 5.9),
        ROOM_H,
        plaster,
        oak,
        [&[], &[], &[], &[]],
        &cuts,
        &[lamp],
    );
}

/// The bedroom: bed, nightstands, wardrobe, desk and chair, a low
/// bookcase and a rug.
pub(super) fn bedroom(s: &mut Interior) {
    let (walnut, pine, linen, oak, paint) =
        (s.m.walnut, s.m.pine, s.m.linen, s.m.oak, s.m.paint_blue);
    s.bed(&Frame::fit(10.1, 7.4, 0.0, 1.6, 2.05, Facing::E));
    s.nightstand(&Frame::fit(10.1, 6.85, 0.0, 0.45, 0.4, Facing::E));
    s.nightstand(&Frame::fit(10.1, 9.1, 0.0, 0.45, 0.4, Facing::E));
    s.cabinet(
        &Frame::fit(12.8, 6.1, 0.0, 2.0, 0.6, Facing::S),
        2.0,
        0.6,
        2.1,
        3,
        walnut,
        pine,
    );
    s.table(
        &Frame::fit(15.0, 11.1, 0.0, 1.4, 0.7, Facing::N),
        1.4,
        0.7,
        0.75,
        pine,
    );
    s.chair(
        &Frame::fit(15.45, 10.45, 0.0, 0.44, 0.44, Facing::S),
        walnut,
        linen,
    );
    s.bookcase(
        &Frame::fit(17.45, 10.3, 0.0, 1.2, 0.35, Facing::W),
        1.2,
        1.2,
        0.35,
        3,
    );
    s.rug((12.3, 14.0), (7.2, 9.2));
    let cuts = s.take_cuts();
    s.room(
        (10.1, 17.8),
        (6.1, 11.8),
        ROOM_H,
        paint,
        oak,
        [&[], &[], &[], &[]],
        &cuts,
        &[],
    );
}

/// The dining room: a table for six, a sideboard, a bookcase between the
/// south windows and an emissive lamp over the table.
pub(super) fn dining(s: &mut Interior) {
    let (walnut, pine, red, tile, paint) = (
        s.m.walnut,
        s.m.pine,
        s.m.fabric_red,
        s.m.tile,
        s.m.paint_sage,
    );
    s.table(
        &Frame::fit(3.8, 9.5, 0.0, 2.4, 1.0, Facing::S),
        2.4,
        1.0,
        0.75,
        walnut,
    );
    for x in [4.05, 4.85, 5.65] {
        s.chair(&Frame::fit(x, 8.95, 0.0, 0.44, 0.44, Facing::S), pine, red);
        s.chair(&Frame::fit(x, 10.6, 0.0, 0.44, 0.44, Facing::N), pine, red);
    }
    s.cabinet(
        &Frame::fit(9.45, 8.4, 0.0, 1.4, 0.45, Facing::W),
        1.4,
        0.45,
        0.85,
        2,
        walnut,
        pine,
    );
    s.bookcase(
        &Frame::fit(4.3, 11.45, 0.0, 1.4, 0.35, Facing::N),
        1.4,
        2.2,
        0.35,
        5,
    );
    let lamp = s.lamp(5.0, 10.0, ROOM_H);
    let cuts = s.take_cuts();
    s.room(
        (0.2, 9.9),
        (8.1, 11.8),
        ROOM_H,
        paint,
        tile,
        [&[], &[], &[], &[]],
        &cuts,
        &[lamp],
    );
}
