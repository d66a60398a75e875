//! The first step of voxelization (the module doc of [`super`]): each
//! triangle's pieces, the voxels it overlaps (a conservative
//! separating-axis test) and the part of it inside each (exact polygon
//! clipping), with area and centroid. The OpenCL kernel
//! `crates/bake/kernels/voxelize.cl` ([`cl_pieces`]) and its CPU reference in f64
//! ([`cpu_pieces`]), in the kernel's output order.

use super::{ClPiece, Piece, KERNEL_SOURCE, SAT_HALF};
use crate::compute::{round_up, Access, Gpu};
use crate::error::BakeError;
use radiosity_core::math::{cross, dot, sub};
use radiosity_core::patch::{clip_to_unit_box, Grid};
use radiosity_core::scene::Scene;
use rayon::prelude::*;

/// The triangles in grid coordinates, 9 values each (f64 on the host; the
/// OpenCL path rounds them to f32).
pub fn grid_coords(scene: &Scene, grid: &Grid) -> Vec<[f64; 9]> {
    scene
        .triangles
        .iter()
        .map(|t| {
            let mut c = [0.0; 9];
            for (i, &vi) in t.iter().enumerate() {
                let g = grid.to_grid(scene.positions[vi as usize]);
                c[3 * i..3 * i + 3].copy_from_slice(&g);
            }
            c
        })
        .collect()
}

/// The separating-axis test of `tri_box_overlap` in the kernel, in f64.
fn tri_box_overlap(v: [[f64; 3]; 3], h: f64) -> bool {
    let [a, b, c] = v;
    for k in 0..3 {
        let lo = a[k].min(b[k]).min(c[k]);
        let hi = a[k].max(b[k]).max(c[k]);
        if lo > h || hi < -h {
            return false;
        }
    }
    let e = [sub(b, a), sub(c, b), sub(a, c)];
    let n = cross(e[0], e[1]);
    let r = h * (n[0].abs() + n[1].abs() + n[2].abs());
    if dot(n, a).abs() > r {
        return false;
    }
    for ei in e {
        for j in 0..3 {
            let (j1, j2) = ((j + 1) % 3, (j + 2) % 3);
            let mut ax = [0.0; 3];
            ax[j1] = ei[j2];
            ax[j2] = -ei[j1];
            let (pa, pb, pc) = (dot(ax, a), dot(ax, b), dot(ax, c));
            let rr = h * (ax[0].abs() + ax[1].abs() + ax[2].abs());
            if pa.min(pb).min(pc) > rr || pa.max(pb).max(pc) < -rr {
                return false;
            }
        }
    }
    true
}

/// Area and centroid of the part of the triangle inside the unit box, as
/// `clip_piece` in the kernel (including the face-ownership rule).
fn clip_piece(v: [[f64; 3]; 3], n: [f64; 3]) -> (f64, [f64; 3]) {
    let poly = clip_to_unit_box(v);
    if poly.len() < 3 {
        return (0.0, [0.0; 3]);
    }
    for k in 0..3 {
        let all_lo = poly.iter().all(|p| p[k] == 0.0);
        let all_hi = poly.iter().all(|p| p[k] == 1.0);
        if (all_lo && n[k] < 0.0) || (all_hi && n[k] > 0.0) {
            return (0.0, [0.0; 3]);
        }
    }
    let nl = dot(n, n).sqrt();
    let (mut area2, mut acc) = (0.0, [0.0; 3]);
    for i in 1..poly.len() - 1 {
        let s = dot(cross(sub(poly[i], poly[0]), sub(poly[i + 1], poly[0])), n) / nl;
        area2 += s;
        for q in 0..3 {
            acc[q] += s * (poly[0][q] + poly[i][q] + poly[i + 1][q]);
        }
    }
    if area2 <= 0.0 {
        return (0.0, [0.0; 3]);
    }
    (0.5 * area2, acc.map(|a| a / (3.0 * area2)))
}

/// The pieces of one triangle: the kernel's `walk`, in f64.
fn walk(t: u32, c: &[f64; 9], dims: [u32; 3], out: &mut Vec<Piece>) {
    let v: [[f64; 3]; 3] = std::array::from_fn(|i| [c[3 * i], c[3 * i + 1], c[3 * i + 2]]);
    let n = cross(sub(v[1], v[0]), sub(v[2], v[0]));
    let an = n.map(f64::abs);
    let w = if an[0] >= an[1] && an[0] >= an[2] {
        0
    } else if an[1] >= an[2] {
        1
    } else {
        2
    };
    let (u, x) = ((w + 1) % 3, (w + 2) % 3);
    let margin = SAT_HALF - 0.5;
    let mut lo = [0i64; 3];
    let mut hi = [0i64; 3];
    for q in 0..3 {
        let mn = v[0][q].min(v[1][q]).min(v[2][q]);
        let mx = v[0][q].max(v[1][q]).max(v[2][q]);
        let top = dims[q] as i64 - 1;
        lo[q] = ((mn - margin).floor() as i64).clamp(0, top);
        hi[q] = ((mx + margin).floor() as i64).clamp(0, top);
    }
    for iu in lo[u]..=hi[u] {
        for ix in lo[x]..=hi[x] {
            let (mut w0, mut w1) = (lo[w], hi[w]);
            if an[w] > 0.0 {
                let (mut wmin, mut wmax) = (f64::INFINITY, f64::NEG_INFINITY);
                for cu in 0..2 {
                    for cx in 0..2 {
                        let (pu, px) = ((iu + cu) as f64, (ix + cx) as f64);
                        let pw = v[0][w] - (n[u] * (pu - v[0][u]) + n[x] * (px - v[0][x])) / n[w];
                        wmin = wmin.min(pw);
                        wmax = wmax.max(pw);
                    }
                }
                w0 = w0.max(wmin.floor() as i64 - 1);
                w1 = w1.min(wmax.floor() as i64 + 1);
            }
            for iw in w0..=w1 {
                let mut cell = [0i64; 3];
                cell[u] = iu;
                cell[x] = ix;
                cell[w] = iw;
                let centred = v.map(|p| std::array::from_fn(|q| p[q] - (cell[q] as f64 + 0.5)));
                if !tri_box_overlap(centred, SAT_HALF) {
                    continue;
                }
                let local = v.map(|p| std::array::from_fn(|q| p[q] - cell[q] as f64));
                let (area, centroid) = clip_piece(local, n);
                out.push(Piece {
                    tri: t,
                    voxel: cell.map(|c| c as u32),
                    area,
                    centroid,
                });
            }
        }
    }
}

/// The CPU reference for the pieces: the kernel's algorithm in f64, in the
/// kernel's output order.
pub fn cpu_pieces(coords: &[[f64; 9]], grid: &Grid) -> Vec<Piece> {
    coords
        .par_iter()
        .enumerate()
        .map(|(t, c)| {
            let mut out = Vec::new();
            walk(t as u32, c, grid.dims, &mut out);
            out
        })
        .flatten()
        .collect()
}

/// Bytes of device memory the pieces of one batch may take.
const PIECE_BATCH_BYTES: u64 = 256 << 20;

/// The pieces on an OpenCL device: count, prefix sum on the host, emit in
/// batches that fit the device's allocation limit. Returns the pieces and
/// the summed kernel time.
pub fn cl_pieces(
    gpu: &Gpu,
    coords: &[[f64; 9]],
    grid: &Grid,
) -> Result<(Vec<Piece>, f64), BakeError> {
    let n = coords.len();
    if n > u32::MAX as usize {
        return Err(BakeError::TooLarge {
            stage: "voxelize",
            detail: format!("{n} triangles exceed the 2^32 limit"),
        });
    }
    let flat: Vec<f32> = coords.iter().flat_map(|c| c.map(|x| x as f32)).collect();
    let program = gpu.build("voxelize.cl", KERNEL_SOURCE, "")?;
    let count_kernel = gpu.kernel(&program, "count_pieces")?;
    let emit_kernel = gpu.kernel(&program, "emit_pieces")?;
    gpu.check_total("voxelize", (flat.len() * 4 + n * 4) as u64)?;
    let tri_buf = gpu.upload("triangle coordinates", &flat, Access::ReadOnly)?;
    let counts_buf = gpu.buffer::<u32>("piece counts", n, Access::WriteOnly)?;
    let [dx, dy, dz] = grid.dims;
    let n_u32 = n as u32;
    let local = gpu.local_size(&count_kernel, 64);
    let mut kernel_seconds = gpu.timed("count_pieces", || unsafe {
        opencl3::kernel::ExecuteKernel::new(&count_kernel)
            .set_arg(&tri_buf)
            .set_arg(&n_u32)
            .set_arg(&dx)
            .set_arg(&dy)
            .set_arg(&dz)
            .set_arg(&counts_buf)
            .set_global_work_size(round_up(n, local))
            .set_local_work_size(local)
            .enqueue_nd_range(gpu.queue())
    })?;
    let counts = gpu.download("piece counts", &counts_buf, n)?;

    // Batches of whole triangles whose pieces fit in one allocation.
    let piece_bytes = std::mem::size_of::<ClPiece>() as u64;
    let budget = (gpu.info().max_mem_alloc_bytes.min(PIECE_BATCH_BYTES) / piece_bytes).max(1);
    let total: u64 = counts.iter().map(|&c| c as u64).sum();
    let mut pieces = Vec::with_capacity(total as usize);
    let local = gpu.local_size(&emit_kernel, 64);
    let mut first = 0usize;
    while first < n {
        let mut last = first;
        let mut offsets = Vec::new();
        let mut batch = 0u64;
        while last < n && (batch + counts[last] as u64 <= budget || last == first) {
            offsets.push(batch);
            batch += counts[last] as u64;
            last += 1;
        }
        gpu.check_alloc("voxel pieces", batch * piece_bytes)?;
        let offsets_buf = gpu.upload("piece offsets", &offsets, Access::ReadOnly)?;
        let out_buf = gpu.buffer::<ClPiece>("voxel pieces", batch as usize, Access::WriteOnly)?;
        let (first_u32, last_u32) = (first as u32, last as u32);
        kernel_seconds += gpu.timed("emit_pieces", || unsafe {
            opencl3::kernel::ExecuteKernel::new(&emit_kernel)
                .set_arg(&tri_buf)
                .set_arg(&first_u32)
                .set_arg(&last_u32)
                .set_arg(&dx)
                .set_arg(&dy)
                .set_arg(&dz)
                .set_arg(&offsets_buf)
                .set_arg(&out_buf)
                .set_global_work_size(round_up(last - first, local))
                .set_local_work_size(local)
                .enqueue_nd_range(gpu.queue())
        })?;
        let batch_pieces = gpu.download("voxel pieces", &out_buf, batch as usize)?;
        pieces.extend(batch_pieces.into_iter().map(|p| Piece {
            tri: p.tri,
            voxel: p.voxel,
            area: p.area as f64,
            centroid: p.centroid.map(|c| c as f64),
        }));
        first = last;
    }
    Ok((pieces, kernel_seconds))
}
