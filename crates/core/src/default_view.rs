//! A camera and lights for a scene that comes without its camera-and-lights
//! file (`NAME.json`, [`crate::scene_config`]): users' OBJ files
//! rarely have one, and `render` or `view` on such a file should show the
//! scene lit, not stop.
//!
//! The choice is made by casting rays into the scene's own BVH, so that it
//! works inside closed rooms as well as around open models, at any scale:
//! - **Inside.** Points of a 7 × 7 × 7 grid over the scene's bounds each
//!   cast [`PROBE_RAYS`] rays over the sphere. A point is *inside* when
//!   nearly no ray meets the back of a surface (the points within solids and
//!   outside closed, inward-facing rooms do), at least half meet the front
//!   of one, and no surface is closer than 3 % of the bounds' diagonal. The
//!   inside point with the most clearance (the middle of the largest room)
//!   holds the eye. It looks along the horizontal direction (of 16) whose
//!   view, a fan of rays over a 60° field tilted 10° down, meets the most
//!   fronts of surfaces, then the farthest ones, from a step back towards
//!   what lies behind it. A ray straight up from it decides the light: a
//!   point light three quarters of the way to the surface above it, or,
//!   where the ray escapes (a courtyard open to the sky), a sun from above.
//! - **Outside**, where no grid point is inside (a single model, a flat
//!   floor, a scene wound outward): the eye on the bounding sphere's
//!   framing distance, from the direction of [`OUTSIDE_DIRECTIONS`] whose
//!   view meets the most fronts of surfaces, lit by a sun from above and
//!   behind the camera.
//!
//! `+y` is up, the OBJ convention. Light powers are in the scene's units
//! and unit-less in effect: renders choose their exposure from the image.

use crate::bvh::Bvh;
use crate::math::{add, cross, dot, norm, normalize, scale, sub};
use crate::scene::Scene;
use crate::scene_config::{Camera, Light, SceneConfig};
use rayon::prelude::*;

/// Rays cast from each probed point (a Fibonacci sphere).
pub const PROBE_RAYS: usize = 128;

/// Grid points per axis over the bounds.
const GRID: usize = 7;

/// Directions from the bounds' centre towards the eye tried for a view
/// from outside, the preferred first (front, above, to the right).
pub const OUTSIDE_DIRECTIONS: [[f64; 3]; 10] = [
    [0.6, 0.5, 1.0],
    [-0.6, 0.5, 1.0],
    [0.6, 0.5, -1.0],
    [-0.6, 0.5, -1.0],
    [0.3, 1.0, 0.3],
    [1.0, 0.4, 0.2],
    [-1.0, 0.4, -0.2],
    [0.3, -1.0, 0.3],
    [0.6, -0.5, 1.0],
    [-0.6, -0.5, -1.0],
];

/// Where the default eye was put.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Placement {
    /// Inside the scene, lit by a point light under the surface above.
    InsidePoint,
    /// Inside the scene, open above, lit by a sun.
    InsideSun,
    /// Outside the scene's bounds, lit by a sun.
    Outside,
}

/// What one probed point sees.
#[derive(Clone, Copy, Debug, Default)]
struct Probe {
    front: usize,
    back: usize,
    /// The nearest hit of any kind (the point's clearance).
    nearest: f64,
}

/// The scene's geometry as the probes need it.
struct Geometry {
    bvh: Bvh,
    /// Unit normal of each leaf-order triangle.
    normals: Vec<[f64; 3]>,
    /// Length of the probe rays: beyond the whole scene.
    far: f64,
}

impl Geometry {
    /// The nearest surface along the unit direction `d` from `o`: its
    /// distance and whether its front faces `o`.
    fn hit(&self, o: [f64; 3], d: [f64; 3]) -> Option<(f64, bool)> {
        let (k, t) = self.bvh.closest_hit(o, scale(d, self.far))?;
        Some((t * self.far, dot(self.normals[k as usize], d) < 0.0))
    }

    fn probe(&self, p: [f64; 3], dirs: &[[f64; 3]]) -> Probe {
        let mut out = Probe {
            nearest: f64::INFINITY,
            ..Probe::default()
        };
        for &d in dirs {
            if let Some((t, front)) = self.hit(p, d) {
                out.nearest = out.nearest.min(t);
                if front {
                    out.front += 1;
                } else {
                    out.back += 1;
                }
            }
        }
        out
    }
}

/// `k` directions spread evenly over the unit sphere (the Fibonacci
/// lattice).
fn sphere(k: usize) -> Vec<[f64; 3]> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..k)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f64 + 0.5) / k as f64;
            let r = (1.0 - y * y).max(0.0).sqrt();
            let a = golden * i as f64;
            [r * a.cos(), y, r * a.sin()]
        })
        .collect()
}

/// The camera and lights a scene without a camera-and-lights file is shown
/// with: those its file gives ([`Scene::authored`], a glTF file's camera
/// and lights) and, for what it does not give, the default
/// ([`default_config`]). The description says which is which.
pub fn config_for(scene: &Scene) -> SceneConfig {
    let a = &scene.authored;
    if a.camera.is_some() && !a.lights.is_empty() {
        let name = scene
            .source
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        return SceneConfig {
            sky: None,
            objects: Vec::new(),
            camera: a.camera.clone().expect("checked"),
            lights: a.lights.clone(),
            units: "metres".to_string(),
            description: format!("the camera and {} light(s) of {name}", a.lights.len()),
            emission: Default::default(),
        };
    }
    let (mut config, _) = default_config(scene);
    if let Some(c) = &a.camera {
        config.camera = c.clone();
        config.description = format!("{}; the camera from the file", config.description);
    }
    if !a.lights.is_empty() {
        config.lights = a.lights.clone();
        config.description = format!(
            "{}; the {} light(s) from the file",
            config.description,
            a.lights.len()
        );
    }
    config
}

/// A camera and lights for `scene` (module doc), with where the eye went.
/// The configuration's description says what was chosen; it validates.
pub fn default_config(scene: &Scene) -> (SceneConfig, Placement) {
    let (lo, hi) = scene.bounds();
    let (lo, hi) = (lo.map(f64::from), hi.map(f64::from));
    let centre = scale(add(lo, hi), 0.5);
    let diag = norm(sub(hi, lo)).max(1e-30);
    let bvh = Bvh::build(&scene.positions, &scene.triangles, [0.0; 3]);
    let geometry = Geometry {
        normals: bvh
            .order
            .iter()
            .map(|&t| scene.triangle_normal(t as usize))
            .collect(),
        bvh,
        far: 4.0 * diag,
    };
    let dirs = sphere(PROBE_RAYS);
    let points: Vec<[f64; 3]> = (0..GRID * GRID * GRID)
        .map(|i| {
            let f = [i % GRID, (i / GRID) % GRID, i / (GRID * GRID)]
                .map(|k| (k as f64 + 0.5) / GRID as f64);
            std::array::from_fn(|a| lo[a] + f[a] * (hi[a] - lo[a]))
        })
        .collect();
    let probes: Vec<Probe> = points
        .par_iter()
        .map(|&p| geometry.probe(p, &dirs))
        .collect();
    // Inside: (almost) no backs seen, at least half fronts, clear of
    // surfaces; the most clearance (the middle of the largest room).
    let inside = probes
        .iter()
        .enumerate()
        .filter(|(_, q)| {
            q.back <= PROBE_RAYS / 64 && 2 * q.front >= PROBE_RAYS && q.nearest >= 0.03 * diag
        })
        .max_by(|(_, a), (_, b)| a.nearest.total_cmp(&b.nearest))
        .map(|(i, _)| points[i]);
    let up = [0.0, 1.0, 0.0];
    let units = "scene units".to_string();
    let name = scene
        .source
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    if let Some(centre_in) = inside {
        // Look along the horizontal direction whose view (a fan of rays
        // over the field of view, tilted down) meets the most fronts of
        // surfaces, then the farthest; from a step back towards what
        // lies behind (a room seen from near its wall).
        let tilt = 10f64.to_radians();
        let fan = |h: [f64; 3]| -> (i64, f64) {
            let (right, cam_up) = basis(h, up);
            let mut score = (0i64, 0.0f64);
            for &(x, y) in &view_grid(60.0) {
                let y = y - tilt.tan();
                let d = normalize(add(h, add(scale(right, x), scale(cam_up, y))));
                match geometry.hit(centre_in, d) {
                    Some((t, true)) => score = (score.0 + 1, score.1 + t),
                    Some((_, false)) => score.0 -= 1,
                    None => {}
                }
            }
            score
        };
        // Ties (a closed room fills every view) go to the farthest view:
        // along a room's length or across its diagonal, not towards the
        // bounds' middle, which may lie in another room.
        let mut best: Option<([f64; 3], (i64, f64))> = None;
        for k in 0..16 {
            let a = k as f64 * std::f64::consts::TAU / 16.0;
            let h = [a.cos(), 0.0, a.sin()];
            let score = fan(h);
            if best.is_none_or(|(_, b)| score.0 > b.0 || (score.0 == b.0 && score.1 > b.1)) {
                best = Some((h, score));
            }
        }
        let h = best.map_or([0.0, 0.0, -1.0], |(h, _)| h);
        let ahead = match geometry.hit(centre_in, h) {
            Some((t, _)) => t,
            None => 0.25 * diag,
        };
        let behind = match geometry.hit(centre_in, scale(h, -1.0)) {
            Some((t, _)) => t,
            None => 0.0,
        };
        let step = 0.6 * behind;
        let eye = sub(centre_in, scale(h, step));
        let reach = ahead + step;
        let d = normalize(sub(scale(h, tilt.cos()), scale(up, tilt.sin())));
        let camera = Camera {
            position: eye.map(|v| v as f32),
            target: add(eye, scale(d, 0.5 * reach)).map(|v| v as f32),
            up: [0.0, 1.0, 0.0],
            fov_y_deg: 60.0,
        };
        let (light, placement, what) = match geometry.hit(eye, up) {
            Some((t, true)) => {
                let p = add(eye, scale(up, 0.75 * t));
                let i = (0.75 * t) * (0.75 * t);
                (
                    Light::Point {
                        position: p.map(|v| v as f32),
                        intensity: [i as f32; 3],
                    },
                    Placement::InsidePoint,
                    "a point light three quarters of the way to the surface above the eye",
                )
            }
            _ => (
                sun(h),
                Placement::InsideSun,
                "a sun from above (the scene is open above the eye)",
            ),
        };
        let config = SceneConfig {
            sky: None,
            objects: Vec::new(),
            camera,
            lights: vec![light],
            units,
            description: format!(
                "default for {name} (no camera-and-lights file): the eye inside the scene at {}, looking across the most surface in view; {what}",
                show(eye)
            ),
            emission: Default::default(),
        };
        return (config, placement);
    }
    // Outside: frame the bounding sphere from the direction whose view
    // meets the most fronts of surfaces.
    let fov = 45f64;
    let distance = 0.5 * diag / (0.5 * fov.to_radians()).sin() * 1.1;
    let grid = view_grid(fov);
    let mut best = (0, i64::MIN);
    for (i, v) in OUTSIDE_DIRECTIONS.iter().enumerate() {
        let v = normalize(*v);
        let eye = add(centre, scale(v, distance));
        let (right, cam_up) = basis(scale(v, -1.0), up);
        let mut score = 0i64;
        for &(x, y) in &grid {
            let d = normalize(add(scale(v, -1.0), add(scale(right, x), scale(cam_up, y))));
            match geometry.hit(eye, d) {
                Some((_, true)) => score += 1,
                Some((_, false)) => score -= 1,
                None => {}
            }
        }
        if score > best.1 {
            best = (i, score);
        }
    }
    let v = normalize(OUTSIDE_DIRECTIONS[best.0]);
    let eye = add(centre, scale(v, distance));
    let camera = Camera {
        position: eye.map(|x| x as f32),
        target: centre.map(|x| x as f32),
        up: [0.0, 1.0, 0.0],
        fov_y_deg: fov as f32,
    };
    let h = normalize([-v[0], 0.0, -v[2]]);
    let config = SceneConfig {
        sky: None,
        objects: Vec::new(),
        camera,
        lights: vec![sun(h)],
        units,
        description: format!(
            "default for {name} (no camera-and-lights file): the eye outside the scene at {}, framing its bounds; a sun from above and behind the eye",
            show(eye)
        ),
        emission: Default::default(),
    };
    (config, Placement::Outside)
}

/// A sun from above, travelling along `h` (horizontal, unit) as much as a
/// third of the way down: light from behind an eye that looks along `h`.
fn sun(h: [f64; 3]) -> Light {
    let d = normalize([h[0] * 0.35, -1.0, h[2] * 0.35]);
    Light::Directional {
        direction: d.map(|x| x as f32),
        irradiance: [1.0; 3],
    }
}

/// Unit right and up vectors of a camera looking along `forward` (unit)
/// with `up` (any vector not parallel to it: the scene's `+y` is never
/// parallel to an [`OUTSIDE_DIRECTIONS`] entry).
fn basis(forward: [f64; 3], up: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    let right = normalize(cross(forward, up));
    (right, cross(right, forward))
}

/// A 9 × 9 grid of image-plane offsets (tangents) over a square view of
/// `fov` degrees.
fn view_grid(fov: f64) -> Vec<(f64, f64)> {
    let t = (0.5 * fov.to_radians()).tan();
    (0..81)
        .map(|i| {
            let (x, y) = ((i % 9) as f64 / 4.0 - 1.0, (i / 9) as f64 / 4.0 - 1.0);
            (x * t, y * t)
        })
        .collect()
}

fn show(p: [f64; 3]) -> String {
    format!("({:.4}, {:.4}, {:.4})", p[0], p[1], p[2])
}
