//! Rows of rays from the real surfaces, traced on the CPU or in batches on
//! an OpenCL device (`crate::trace`), with the same answer either way.
//!
//! A stage describes a row (an emitter patch) by two functions: one draws
//! its rays ([`Ray`]: origin, surface normal, direction) and may keep
//! something about the row (its covered origins, say); the other turns the
//! rays' hits ([`Hit`], classified on the host by [`Tracer::resolve`]) into
//! the row's result, which a sink takes in row order. On the CPU each row
//! is drawn, traced and consumed by one thread, as before the device path
//! existed; on a device the rows of a batch of about
//! [`crate::trace::BATCH_RAYS`] rays are drawn in parallel, their segments
//! traced by one launch and their hits classified in parallel. The nearest
//! hit of a segment is the same on both (`crate::trace`), so the rows are
//! too.

use super::tracer::{Hit, Tracer};
use crate::error::BakeError;
use crate::trace::{DeviceTracer, BATCH_RAYS};
use radiosity_core::math::scale;
use rayon::prelude::*;

/// One ray of a row: its origin `x` on a surface of normal `n`, and its
/// unit direction `d`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Ray {
    pub x: [f64; 3],
    pub n: [f64; 3],
    pub d: [f64; 3],
}

/// Rows per CPU chunk between progress reports.
const CPU_ROWS_PER_CHUNK: usize = 256;

/// Traces rows `0..rows` (module doc): `draw(i, rays)` fills row `i`'s
/// rays (about `rays_per_row`, which sizes a device batch) and returns
/// what the row keeps; `consume(i, kept, rays, hits)` gives its result,
/// which `sink(i, result)` takes in increasing `i`. `progress(done,
/// total)` counts rows. With `device`, the traversal runs there.
#[allow(clippy::too_many_arguments)]
pub(crate) fn trace_rows<P: Send, R: Send>(
    tracer: &Tracer,
    device: Option<&mut DeviceTracer>,
    rows: usize,
    rays_per_row: usize,
    draw: impl Fn(usize, &mut Vec<Ray>) -> P + Sync,
    consume: impl Fn(usize, P, &[Ray], &[Hit]) -> R + Sync,
    sink: &mut dyn FnMut(usize, R),
    progress: &mut dyn FnMut(u64, u64),
) -> Result<(), BakeError> {
    let Some(device) = device else {
        for start in (0..rows).step_by(CPU_ROWS_PER_CHUNK) {
            let end = (start + CPU_ROWS_PER_CHUNK).min(rows);
            let out: Vec<R> = (start..end)
                .into_par_iter()
                .map_init(Vec::new, |rays, i| {
                    rays.clear();
                    let kept = draw(i, rays);
                    let hits: Vec<Hit> = rays.iter().map(|r| tracer.trace(r.x, r.n, r.d)).collect();
                    consume(i, kept, rays, &hits)
                })
                .collect();
            for (k, r) in out.into_iter().enumerate() {
                sink(start + k, r);
            }
            progress(end as u64, rows as u64);
        }
        return Ok(());
    };
    let chunk = (BATCH_RAYS / rays_per_row.max(1)).max(1);
    for start in (0..rows).step_by(chunk) {
        let end = (start + chunk).min(rows);
        let drawn: Vec<(Vec<Ray>, P)> = (start..end)
            .into_par_iter()
            .map(|i| {
                let mut rays = Vec::with_capacity(rays_per_row);
                let kept = draw(i, &mut rays);
                (rays, kept)
            })
            .collect();
        // The segments, three f64 each for origins and directions.
        let total: usize = drawn.iter().map(|(r, _)| r.len()).sum();
        let (mut o, mut d) = (vec![0.0f64; 3 * total], vec![0.0f64; 3 * total]);
        let mut far = 0.0;
        {
            let (mut os, mut ds) = (o.as_mut_slice(), d.as_mut_slice());
            let mut parts = Vec::with_capacity(drawn.len());
            for (rays, _) in &drawn {
                let (a, rest_o) = std::mem::take(&mut os).split_at_mut(3 * rays.len());
                let (b, rest_d) = std::mem::take(&mut ds).split_at_mut(3 * rays.len());
                os = rest_o;
                ds = rest_d;
                parts.push((rays, a, b));
            }
            if let Some(r) = drawn.iter().flat_map(|(r, _)| r.first()).next() {
                far = tracer.segment(r.x, r.n).1;
            }
            parts.into_par_iter().for_each(|(rays, a, b)| {
                for (k, r) in rays.iter().enumerate() {
                    let (s, f) = tracer.segment(r.x, r.n);
                    a[3 * k..3 * k + 3].copy_from_slice(&s);
                    b[3 * k..3 * k + 3].copy_from_slice(&scale(r.d, f));
                }
            });
        }
        let nearest = device.closest(&o, &d)?;
        drop(d);
        let mut offsets = Vec::with_capacity(drawn.len());
        let mut at = 0usize;
        for (rays, _) in &drawn {
            offsets.push(at);
            at += rays.len();
        }
        let out: Vec<R> = drawn
            .into_par_iter()
            .zip(offsets)
            .enumerate()
            .map(|(k, ((rays, kept), at))| {
                let hits: Vec<Hit> = rays
                    .iter()
                    .enumerate()
                    .map(|(m, r)| {
                        let q = 3 * (at + m);
                        let s = [o[q], o[q + 1], o[q + 2]];
                        tracer.resolve(s, r.d, nearest[at + m], far)
                    })
                    .collect();
                consume(start + k, kept, &rays, &hits)
            })
            .collect();
        for (k, r) in out.into_iter().enumerate() {
            sink(start + k, r);
        }
        progress(end as u64, rows as u64);
    }
    Ok(())
}
