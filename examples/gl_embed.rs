//! Embedding the GL run time in an application that owns its OpenGL
//! context: `GlRenderer` needs only a `glow::Context` current on the
//! calling thread — the application's own (a game's, an editor's), made
//! with any windowing library. Here a headless EGL context stands in for
//! it. Each frame the GPU computes the shadow maps, `D` on the patches,
//! `B0` and the gather `H`; the application reads `H` back (or binds
//! `radiance_texture` after `render`), and draws its own frame around it.
//!
//! ```sh
//! cargo run --release --example gl_embed -- BAKE.rad
//! ```
//!
//! `tests/gl_render.rs` runs [`run`] on a bake of the Cornell box and
//! checks its `H` against the CPU run time's.

use radiosity::core::scene_config::Light;
use radiosity::gl::renderer::{GlOptions, GlRenderer};
use radiosity::runtime::{Runtime, RuntimeOptions};
use std::collections::BTreeMap;
use std::path::Path;

/// `H` per patch after one frame lit by `lights`, from the GPU, with the
/// CPU run time's for the same frame.
pub struct Compared {
    pub gpu: [Vec<f32>; 3],
    pub cpu: [Vec<f32>; 3],
}

/// Opens `bake`, lights it with `lights` on the GPU through `gl` (a
/// context the caller owns, current on this thread) and on the CPU.
pub fn run(
    gl: &glow::Context,
    bake: &Path,
    lights: &[Light],
) -> Result<Compared, Box<dyn std::error::Error>> {
    let mut rt = Runtime::open(bake, None, RuntimeOptions::default())?;
    // Uploads the bake and the scene into the caller's context.
    let mut renderer = GlRenderer::new(gl, &rt, GlOptions::default())?;
    let emission = BTreeMap::new(); // every material's Ke at scale 1
    renderer.frame(gl, lights, &emission)?;
    let gpu = renderer.h(gl);
    // The GL objects belong to the caller's context: freed in it.
    renderer.delete(gl);
    rt.frame(lights, &emission);
    Ok(Compared {
        gpu,
        cpu: rt.h().clone(),
    })
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let bake = std::env::args().nth(1).ok_or("usage: gl_embed BAKE.rad")?;
    // The application's context; here a headless one.
    let ctx = radiosity::gl::context::Headless::new()?;
    let rt = Runtime::open(Path::new(&bake), None, RuntimeOptions::default())?;
    let (lo, hi) = rt.scene.bounds();
    let centre: [f32; 3] = std::array::from_fn(|k| 0.5 * (lo[k] + hi[k]));
    let size = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f32::max);
    let lights = vec![Light::Point {
        position: centre,
        intensity: [size * size; 3],
    }];
    let c = run(&ctx.gl, Path::new(&bake), &lights)?;
    let mean = |h: &[Vec<f32>; 3]| h[0].iter().sum::<f32>() / h[0].len().max(1) as f32;
    println!(
        "{} patches on {}: mean H (red) {:.6} on the GPU, {:.6} on the CPU",
        c.gpu[0].len(),
        ctx.device,
        mean(&c.gpu),
        mean(&c.cpu)
    );
    Ok(())
}
