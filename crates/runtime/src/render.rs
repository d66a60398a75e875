//! The CPU reference renderer: one primary ray per pixel against the
//! original triangles (the BVH), direct light at the hit with shadow rays
//! (the one light definition of [`radiosity_core::light`]), `H` from the
//! surface map ([`super::surface`]), the full-resolution albedo
//! ([`super::texture`]), then exposure, tone mapping and sRGB
//! ([`super::tonemap`]).
//!
//! The views are radiances (docs/design.md section 2): final `L = ρ/π · (D + H) +
//! Le`, direct `ρ/π · D + Le`, indirect `ρ/π · H`, and patches (`ρ_j/π ·
//! H_j` of the patch that stands for the pixel's surface, flat per patch).
//! `Le = s_m Ke / π` (`Ke` is an exitance). Surfaces seen from behind (the
//! side opposite their winding, which receives and emits nothing) are
//! black, and counted.

use super::surface::{self, Lookup};
use super::texture::Albedo;
use super::Runtime;
use radiosity_core::bvh4::PACKET;
use radiosity_core::direct::ShadowCache;
use radiosity_core::math::{add, cross, dot, normalize, scale, sub};
use radiosity_core::scene_config::{Camera, SceneConfig};
use rayon::prelude::*;
use std::f64::consts::PI;
use std::time::Instant;

/// What a pixel shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum View {
    Final,
    Direct,
    Indirect,
    Patches,
    /// The surface map's weights: `Σ w_k c(p_k)` over the patches that
    /// light the point, each patch its own colour [`patch_colour`].
    Weights,
}

/// A patch's colour in the weights view (crates/gl/glsl/shade.frag mirrors it): the
/// bytes of a multiplicative hash of its index, in [0.2, 1].
pub fn patch_colour(p: u32) -> [f32; 3] {
    let h = p.wrapping_mul(2_654_435_761);
    [h & 255, (h >> 8) & 255, (h >> 16) & 255].map(|b| 0.2 + 0.8 * b as f32 / 255.0)
}

impl View {
    pub fn parse(s: &str) -> Option<View> {
        Some(match s {
            "final" => View::Final,
            "direct" => View::Direct,
            "indirect" => View::Indirect,
            "patches" => View::Patches,
            "weights" => View::Weights,
            _ => return None,
        })
    }
}

/// A rendered image: linear radiance per pixel, top row first.
#[derive(Clone, Debug)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    pub radiance: Vec<[f32; 3]>,
    /// Pixels that see a front-facing surface.
    pub covered: Vec<bool>,
}

impl Image {
    /// The relative RMS difference of this image from `reference` over the
    /// pixels both cover (`√(Σ (a − r)² / Σ r²)`, three channels pooled), and
    /// the share of pixels whose coverage differs: how the GL renderer is
    /// compared with this one (`bench frame`, tests/gl_render.rs).
    pub fn difference(&self, reference: &Image) -> (f64, f64) {
        assert_eq!(
            (self.width, self.height),
            (reference.width, reference.height),
            "images of different sizes"
        );
        let (mut num, mut den, mut differ) = (0.0f64, 0.0f64, 0usize);
        for i in 0..self.radiance.len() {
            if self.covered[i] != reference.covered[i] {
                differ += 1;
                continue;
            }
            if !self.covered[i] {
                continue;
            }
            for c in 0..3 {
                let (a, r) = (
                    f64::from(self.radiance[i][c]),
                    f64::from(reference.radiance[i][c]),
                );
                num += (a - r).powi(2);
                den += r.powi(2);
            }
        }
        (
            (num / den.max(1e-300)).sqrt(),
            differ as f64 / self.radiance.len().max(1) as f64,
        )
    }
}

/// Counts and times of one image.
#[derive(Clone, Debug, Default)]
pub struct RenderStats {
    pub pixels: u64,
    pub hits: u64,
    pub back_faces: u64,
    /// Surface-map lookups through a nearest piece, and unmapped pixels.
    pub nearest_piece: u64,
    pub unmapped: u64,
    pub seconds: f64,
}

/// The pinhole camera's ray through pixel centre `(px, py)`.
pub struct Rays {
    eye: [f64; 3],
    forward: [f64; 3],
    right: [f64; 3],
    up: [f64; 3],
    tan: f64,
    aspect: f64,
    width: usize,
    height: usize,
}

impl Rays {
    pub fn new(camera: &Camera, width: usize, height: usize) -> Rays {
        let eye = camera.position.map(f64::from);
        let forward = normalize(sub(camera.target.map(f64::from), eye));
        let right = normalize(cross(forward, camera.up.map(f64::from)));
        let up = cross(right, forward);
        Rays {
            eye,
            forward,
            right,
            up,
            tan: (camera.fov_y_deg as f64 * PI / 360.0).tan(),
            aspect: width as f64 / height as f64,
            width,
            height,
        }
    }

    /// Origin and unit direction through the centre of pixel `(px, py)`.
    pub fn ray(&self, px: usize, py: usize) -> ([f64; 3], [f64; 3]) {
        let x = (2.0 * (px as f64 + 0.5) / self.width as f64 - 1.0) * self.tan * self.aspect;
        let y = (1.0 - 2.0 * (py as f64 + 0.5) / self.height as f64) * self.tan;
        let d = normalize(add(
            self.forward,
            add(scale(self.right, x), scale(self.up, y)),
        ));
        (self.eye, d)
    }
}

/// Renders `view` of the runtime's last frame (`rt.h()`) from the camera of
/// `config`, with its lights (direct light at pixels is recomputed with
/// shadow rays) and emission scales.
pub fn render(
    rt: &Runtime,
    config: &SceneConfig,
    view: View,
    width: usize,
    height: usize,
    albedo: &Albedo,
) -> (Image, RenderStats) {
    let (camera, scales) = (&config.camera, &config.emission);
    let lights = &radiosity_core::light::Prepared::all(&config.frame_lights())[..];
    let start = Instant::now();
    let scene = &rt.scene;
    let bvh = rt.direct.bvh();
    let rays = Rays::new(camera, width, height);
    let far = 4.0 * rt.direct.far();
    let h = rt.h();
    // The sky: its direct light per pixel is the patches' `D_sky` through
    // the surface map (the weights `H` takes), and it is seen where a
    // camera ray leaves the scene.
    let d_sky = rt.d_sky();
    let sky = rt
        .sky()
        .filter(|_| matches!(view, View::Final | View::Direct))
        .map(|s| s.prepared());
    let map = &rt.baked.surface_map;
    let h_points = rt.h_points();
    let rows: Vec<(Vec<[f32; 3]>, Vec<bool>, RenderStats)> = (0..height)
        .into_par_iter()
        .map(|py| {
            let mut s = RenderStats::default();
            let mut row = vec![[0.0f32; 3]; width];
            let mut cov = vec![false; width];
            // Neighbouring pixels share their shadows' blockers.
            let mut shadows = ShadowCache::new(lights.len());
            // Primary rays eight pixels at a time (neighbouring camera
            // rays share most of their nodes).
            let mut hits = [None; PACKET];
            let mut rays8 = [([0.0f64; 3], [0.0f64; 3]); PACKET];
            for px in 0..width {
                s.pixels += 1;
                let lane = px % PACKET;
                if lane == 0 {
                    let live = (width - px).min(PACKET);
                    for (k, r) in rays8.iter_mut().enumerate().take(live) {
                        *r = rays.ray(px + k, py);
                    }
                    let o = rays8.map(|r| r.0);
                    let seg = rays8.map(|r| scale(r.1, far));
                    let mask = ((1u16 << live) - 1) as u8;
                    hits = rt.direct.closest_hit_packet(&o, &seg, mask);
                }
                let (o, d) = rays8[lane];
                let Some((k, t)) = hits[lane] else {
                    if let Some(sky) = &sky {
                        let l = sky.radiance(normalize(d));
                        row[px] = l.map(|v| v as f32);
                    }
                    continue;
                };
                s.hits += 1;
                let mut tri = bvh.order[k as usize] as usize;
                if dot(scene.triangle_normal(tri), d) >= 0.0 {
                    // The coincident twin faces the camera, if the face has
                    // one (`Scene::twin`).
                    match scene.twin(tri) {
                        Some(twin) => tri = twin,
                        None => {
                            s.back_faces += 1;
                            continue;
                        }
                    }
                }
                let ng = scene.triangle_normal(tri);
                cov[px] = true;
                let x = add(o, scale(d, t * far));
                let m = scene.triangle_material[tri] as usize;
                let rho = albedo.at(scene, m, texcoord(scene, tri, x));
                let mat = &scene.materials[m];
                let es = scales.get(&mat.name).copied().unwrap_or(1.0);
                let le: [f64; 3] = std::array::from_fn(|c| (es * mat.emission[c]) as f64 / PI);
                let xf = x.map(|v| v as f32);
                let (w, how) = surface::weights(map, tri, xf);
                match how {
                    Lookup::Piece => {}
                    Lookup::NearestPiece => s.nearest_piece += 1,
                    Lookup::Unmapped => s.unmapped += 1,
                }
                let mut hx = surface::apply(&w, h);
                if let Some(hp) = h_points {
                    // How H spreads over the receiver near its neighbours
                    // (never below 0: a deviation larger than H is noise).
                    let dev = surface::at_cells(&w, map, xf, hp);
                    for c in 0..3 {
                        hx[c] = (hx[c] + dev[c]).max(0.0);
                    }
                }
                let sx = match d_sky {
                    Some(ds) if matches!(view, View::Final | View::Direct) => {
                        surface::apply(&w, ds)
                    }
                    _ => [0.0; 3],
                };
                let dx = if matches!(view, View::Final | View::Direct) {
                    rt.direct.at_point_cached(x, ng, lights, &mut shadows)
                } else {
                    [0.0; 3]
                };
                row[px] = std::array::from_fn(|c| {
                    let r = rho[c] as f64 / PI;
                    (match view {
                        View::Weights => w
                            .iter()
                            .filter(|_| how != Lookup::Unmapped)
                            .map(|&(p, wt)| wt as f64 * patch_colour(p)[c] as f64)
                            .sum(),
                        View::Final => r * (dx[c] + sx[c] as f64 + hx[c] as f64) + le[c],
                        View::Direct => r * (dx[c] + sx[c] as f64) + le[c],
                        View::Indirect => r * hx[c] as f64,
                        View::Patches => {
                            if how == Lookup::Unmapped {
                                0.0
                            } else {
                                let p = w[0].0 as usize;
                                rt.baked.patches[p].albedo[c] as f64 / PI * h[c][p] as f64
                            }
                        }
                    }) as f32
                });
            }
            (row, cov, s)
        })
        .collect();
    let mut img = Image {
        width,
        height,
        radiance: Vec::with_capacity(width * height),
        covered: Vec::with_capacity(width * height),
    };
    let mut stats = RenderStats::default();
    for (row, cov, s) in rows {
        img.radiance.extend(row);
        img.covered.extend(cov);
        stats.pixels += s.pixels;
        stats.hits += s.hits;
        stats.back_faces += s.back_faces;
        stats.nearest_piece += s.nearest_piece;
        stats.unmapped += s.unmapped;
    }
    stats.seconds = start.elapsed().as_secs_f64();
    (img, stats)
}

/// The texture coordinates at `x` on triangle `t` (barycentric), if the
/// scene has them.
fn texcoord(scene: &radiosity_core::scene::Scene, t: usize, x: [f64; 3]) -> Option<[f32; 2]> {
    if scene.texcoords.is_empty() {
        return None;
    }
    let [a, b, c] = scene.triangles[t].map(|v| v as usize);
    let p = |i: usize| scene.positions[i].map(f64::from);
    let (pa, pb, pc) = (p(a), p(b), p(c));
    let n = cross(sub(pb, pa), sub(pc, pa));
    let nn = dot(n, n);
    if !(nn > 0.0) {
        return None;
    }
    let wb = dot(cross(sub(x, pa), sub(pc, pa)), n) / nn;
    let wc = dot(cross(sub(pb, pa), sub(x, pa)), n) / nn;
    let wa = 1.0 - wb - wc;
    let (ta, tb, tc) = (scene.texcoords[a], scene.texcoords[b], scene.texcoords[c]);
    Some(std::array::from_fn(|k| {
        (wa * ta[k] as f64 + wb * tb[k] as f64 + wc * tc[k] as f64) as f32
    }))
}

impl Image {
    /// 8-bit sRGB pixels with `exposure` (automatic when `None`: module doc
    /// of [`super::tonemap`]); returns the exposure used.
    pub fn to_srgb8(&self, exposure: Option<f32>) -> (Vec<u8>, f32) {
        let k = exposure.unwrap_or_else(|| {
            super::tonemap::auto_exposure(
                self.radiance
                    .iter()
                    .zip(&self.covered)
                    .filter(|(_, &c)| c)
                    .map(|(p, _)| p),
            )
        });
        let mut out = Vec::with_capacity(3 * self.radiance.len());
        for p in &self.radiance {
            out.extend_from_slice(&super::tonemap::to_srgb8(*p, k));
        }
        (out, k)
    }
}
