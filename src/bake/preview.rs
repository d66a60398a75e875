//! A software preview of the voxel patches: each patch drawn as a square of
//! its area in its plane, coloured by its albedo (emitters in white), seen
//! from the scene's camera. Written by `bake --export` as `patches.png` so
//! that a user can see what the simplification kept, without a GPU.
//! Patches facing away from the camera are culled.

use crate::core::math::{cross, dot, normalize, sub};
use crate::core::patch::Patch;
use crate::core::patch::CORNERS;
use crate::core::scene_config::Camera;
use image::{Rgb, RgbImage};

/// A pinhole camera as a view basis.
struct View {
    eye: [f64; 3],
    right: [f64; 3],
    up: [f64; 3],
    forward: [f64; 3],
    /// 1 / tan(fov_y / 2).
    focal: f64,
}

impl View {
    fn new(c: &Camera) -> View {
        let f64s = |v: [f32; 3]| v.map(|x| x as f64);
        let eye = f64s(c.position);
        let forward = normalize(sub(f64s(c.target), eye));
        let right = normalize(cross(forward, f64s(c.up)));
        let up = cross(right, forward);
        View {
            eye,
            right,
            up,
            forward,
            focal: 1.0 / (c.fov_y_deg as f64 * 0.5).to_radians().tan(),
        }
    }
}

/// A camera for a scene without a camera file: inside, at the centre of the
/// bounds a third of the way up, looking along the longer horizontal axis
/// (architectural scenes are seen from within; back faces are culled, so a
/// closed model seen from outside would show nothing).
pub fn default_camera(bounds: ([f32; 3], [f32; 3])) -> Camera {
    let (lo, hi) = bounds;
    let mut eye: [f32; 3] = std::array::from_fn(|a| 0.5 * (lo[a] + hi[a]));
    eye[1] = lo[1] + 0.33 * (hi[1] - lo[1]);
    let mut target = eye;
    if hi[0] - lo[0] >= hi[2] - lo[2] {
        target[0] = hi[0];
    } else {
        target[2] = hi[2];
    }
    target[1] = eye[1] + 0.15 * (hi[1] - lo[1]);
    Camera {
        position: eye,
        target,
        up: [0.0, 1.0, 0.0],
        fov_y_deg: 70.0,
    }
}

/// Draws the patches as seen from `camera` into a `width × height` image.
pub fn render_patches(patches: &[Patch], camera: &Camera, width: u32, height: u32) -> RgbImage {
    let view = View::new(camera);
    let (w, h) = (width as usize, height as usize);
    let mut depth = vec![f64::INFINITY; w * h];
    let mut img = RgbImage::from_pixel(width, height, Rgb([24, 24, 32]));
    let aspect = width as f64 / height as f64;
    for p in patches {
        // The patch's square, in its plane, of side sqrt(area).
        let frame = p.frame();
        let n = frame.n;
        let corners: Vec<[f64; 3]> = CORNERS
            .iter()
            .map(|&(a, b)| p.point(&frame, a, b))
            .collect();
        // Screen positions; skip patches reaching behind the eye.
        let mut screen = [[0.0f64; 3]; 4];
        let mut visible = true;
        for (s, c) in screen.iter_mut().zip(&corners) {
            let d = sub(*c, view.eye);
            let z = dot(d, view.forward);
            if z <= 1e-6 {
                visible = false;
                break;
            }
            let x = dot(d, view.right) * view.focal / (z * aspect);
            let y = dot(d, view.up) * view.focal / z;
            *s = [(x + 1.0) * 0.5 * w as f64, (1.0 - y) * 0.5 * h as f64, z];
        }
        if !visible {
            continue;
        }
        // Patches are one-sided: the back of a wall is not drawn.
        let to_eye = normalize(sub(view.eye, p.centre));
        if dot(n, to_eye) <= 0.0 {
            continue;
        }
        // Albedo, lit by a headlight so orientation reads; emitters white.
        let shade = 0.35 + 0.65 * dot(n, to_eye);
        let emissive = p.emission.iter().any(|&e| e > 0.0);
        let colour: [u8; 3] = std::array::from_fn(|c| {
            let linear = if emissive { 1.0 } else { p.albedo[c] * shade };
            (255.0 * linear.clamp(0.0, 1.0).powf(1.0 / 2.2)).round() as u8
        });
        for tri in [[0, 1, 2], [0, 2, 3]] {
            fill_triangle(&mut img, &mut depth, tri.map(|i| screen[i]), colour);
        }
    }
    img
}

/// Fills a screen-space triangle with a depth test (depth interpolated
/// linearly in screen space, enough for a preview).
fn fill_triangle(img: &mut RgbImage, depth: &mut [f64], t: [[f64; 3]; 3], colour: [u8; 3]) {
    let (w, h) = (img.width() as i64, img.height() as i64);
    let edge = |a: [f64; 3], b: [f64; 3], x: f64, y: f64| {
        (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0])
    };
    let area = edge(t[0], t[1], t[2][0], t[2][1]);
    if area.abs() < 1e-12 {
        return;
    }
    let x0 = t
        .iter()
        .map(|p| p[0])
        .fold(f64::INFINITY, f64::min)
        .floor()
        .max(0.0) as i64;
    let x1 = (t
        .iter()
        .map(|p| p[0])
        .fold(f64::NEG_INFINITY, f64::max)
        .ceil() as i64)
        .min(w - 1);
    let y0 = t
        .iter()
        .map(|p| p[1])
        .fold(f64::INFINITY, f64::min)
        .floor()
        .max(0.0) as i64;
    let y1 = (t
        .iter()
        .map(|p| p[1])
        .fold(f64::NEG_INFINITY, f64::max)
        .ceil() as i64)
        .min(h - 1);
    for y in y0..=y1 {
        for x in x0..=x1 {
            let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
            let b0 = edge(t[1], t[2], px, py) / area;
            let b1 = edge(t[2], t[0], px, py) / area;
            let b2 = 1.0 - b0 - b1;
            if b0 < 0.0 || b1 < 0.0 || b2 < 0.0 {
                continue;
            }
            let z = b0 * t[0][2] + b1 * t[1][2] + b2 * t[2][2];
            let i = (y * w + x) as usize;
            if z < depth[i] {
                depth[i] = z;
                img.put_pixel(x as u32, y as u32, Rgb(colour));
            }
        }
    }
}
