//! Embedding the CPU run time in an application (README, "Using the run
//! time from Rust"): open a bake, light it with a light that moves, and
//! read the indirect light per patch and at a point of the scene.
//!
//! ```sh
//! cargo run --release --example embed -- BAKE.rad [FRAMES]
//! ```
//!
//! `tests/runtime.rs` runs [`run`] on a bake of the Cornell box.

use radiosity::core::scene_config::Light;
use radiosity::runtime::open::OpenError;
use radiosity::runtime::{Runtime, RuntimeOptions};
use std::collections::BTreeMap;
use std::path::Path;

/// What one frame computed, at a probe point below the scene's centre.
#[derive(Clone, Debug)]
pub struct Frame {
    /// Wall-clock milliseconds of `Runtime::frame`.
    pub ms: f64,
    /// Products recomputed (the moved light) and reused (the emission).
    pub terms_computed: usize,
    pub terms_reused: usize,
    /// Direct and indirect irradiance at the probe (W/m²).
    pub direct: [f64; 3],
    pub indirect: [f32; 3],
    /// The mean indirect irradiance over the patches.
    pub mean_h: [f32; 3],
    /// The probe (triangle, point), if the ray down from the centre met a
    /// front face, and the frame's light.
    pub probe: Option<(usize, [f64; 3])>,
    pub light: Light,
}

/// `frames` frames of a spot light hanging above the probe of the bake at
/// `bake`, swinging around it (the first surface straight below the
/// scene's centre).
pub fn run(bake: &Path, frames: usize) -> Result<Vec<Frame>, OpenError> {
    // The bake file and its scene (found where the bake names it: shadow
    // rays and textures need the real triangles), checked to belong
    // together.
    let mut rt = Runtime::open(bake, None, RuntimeOptions::default())?;
    let (lo, hi) = rt.scene.bounds();
    let centre: [f64; 3] = std::array::from_fn(|k| 0.5 * (lo[k] as f64 + hi[k] as f64));
    let size = (0..3).map(|k| (hi[k] - lo[k]) as f64).fold(0.0, f64::max);
    // A probe: the surface straight below the centre (the floor), with
    // the normal of its triangle.
    let probe = rt.first_hit(centre, [0.0, -1.0, 0.0]);
    let emission = BTreeMap::new(); // every material's Ke at scale 1
    let mut out = Vec::with_capacity(frames);
    for f in 0..frames {
        let a = std::f64::consts::TAU * f as f64 / frames.max(1) as f64;
        // A spot hanging above the probe along its normal (lower where
        // something is in the way), swinging around it.
        let (target, n) = probe.map_or(
            ([centre[0], lo[1] as f64, centre[2]], [0.0, 1.0, 0.0]),
            |p| (p.1, rt.scene.triangle_normal(p.0)),
        );
        let lifted = |h: f64| -> [f64; 3] { std::array::from_fn(|k| target[k] + h * n[k]) };
        let mut h = 0.2 * size;
        while h > 1e-3 * size && !rt.direct.visible(lifted(1e-3 * size), lifted(h)) {
            h *= 0.5;
        }
        let position = lifted(h);
        let aim: [f64; 3] = std::array::from_fn(|k| {
            target[k] + 0.1 * size * [a.cos(), 0.0, a.sin()][k] - position[k]
        });
        let light = Light::Spot {
            position: position.map(|v| v as f32),
            direction: aim.map(|v| v as f32),
            intensity: [0.5 * (size * size) as f32; 3],
            cone_angle_deg: 40.0,
            beam_angle_deg: 30.0,
        };
        // One frame: direct light on the patches, B0, the gather of the
        // moved light's columns; the emission's product is reused.
        let stats = rt.frame(std::slice::from_ref(&light), &emission);
        // Per patch: `rt.h()` (upload it as a buffer and evaluate the
        // surface map in your shader, or read it here). At a point:
        let (direct, indirect) = match probe {
            Some((tri, x)) => {
                let n = rt.scene.triangle_normal(tri);
                let d = rt.direct.at_points(&[(x, n)], std::slice::from_ref(&light));
                (d, rt.indirect_at(tri, x.map(|v| v as f32)))
            }
            None => ([0.0; 3], [0.0; 3]),
        };
        let mean_h = std::array::from_fn(|c| {
            (rt.h()[c].iter().map(|&v| v as f64).sum::<f64>() / rt.n() as f64) as f32
        });
        out.push(Frame {
            ms: 1e3 * stats.seconds_total,
            terms_computed: stats.terms_computed,
            terms_reused: stats.terms_reused,
            direct,
            indirect,
            mean_h,
            probe,
            light,
        });
    }
    Ok(out)
}

#[allow(dead_code)] // `tests/runtime.rs` includes this file for `run`.
fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(bake), frames) = (args.first(), args.get(1)) else {
        eprintln!("usage: embed BAKE.rad [FRAMES]");
        std::process::exit(2);
    };
    let frames = match frames.map(|s| s.parse::<usize>()) {
        None => 8,
        Some(Ok(k)) if (1..=100_000).contains(&k) => k,
        Some(_) => {
            eprintln!("FRAMES: expected 1..=100000, got {:?}", args[1]);
            std::process::exit(2);
        }
    };
    match run(Path::new(bake), frames) {
        Ok(fs) => {
            println!("| frame | ms | terms computed / reused | D at the probe | H at the probe | mean H |");
            println!("|---|---|---|---|---|---|");
            for (k, f) in fs.iter().enumerate() {
                println!(
                    "| {k} | {:.2} | {} / {} | {:.3?} | {:.3?} | {:.3?} |",
                    f.ms, f.terms_computed, f.terms_reused, f.direct, f.indirect, f.mean_h
                );
            }
        }
        Err(e) => {
            eprint!("error: {e}");
            let mut s = std::error::Error::source(&e);
            while let Some(c) = s {
                eprint!("\n  caused by: {c}");
                s = c.source();
            }
            eprintln!();
            std::process::exit(1);
        }
    }
}
