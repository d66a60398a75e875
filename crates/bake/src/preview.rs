//! A software preview of the voxel patches: each patch drawn as its real
//! region, the triangle pieces the voxelizer gave it, in the patch's albedo
//! (emitters in white), with neighbouring patches told apart by a slight
//! change of shade, seen from the scene's camera. Pieces that belong to no
//! kept patch (covered geometry, patches that see nothing) are drawn in
//! dark magenta. Written by `bake --export` as `patches.png` so that a user
//! can see what the simplification kept, without a GPU. Back faces are
//! culled.

use crate::pieces::PieceGeo;
use image::{Rgb, RgbImage};
use radiosity_core::math::{cross, dot, normalize, sub};
use radiosity_core::patch::Patch;
use radiosity_core::scene_config::Camera;

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

/// The colour of pieces that belong to no kept patch.
pub const UNOWNED: [u8; 3] = [96, 24, 96];

/// Draws the pieces as seen from `camera` into a `width × height` image,
/// each in the colour of its patch (`owner[k]`, an index into `patches`, or
/// `None`: [`UNOWNED`]).
pub fn render_pieces(
    pieces: &[PieceGeo],
    owner: &[Option<u32>],
    patches: &[Patch],
    camera: &Camera,
    width: u32,
    height: u32,
) -> RgbImage {
    let view = View::new(camera);
    let (w, h) = (width as usize, height as usize);
    let mut depth = vec![f64::INFINITY; w * h];
    let mut img = RgbImage::from_pixel(width, height, Rgb([24, 24, 32]));
    let aspect = width as f64 / height as f64;
    for (piece, owner) in pieces.iter().zip(owner) {
        let Some(first) = piece.poly.first() else {
            continue;
        };
        // One-sided: the back of a wall is not drawn.
        let to_eye = normalize(sub(view.eye, *first));
        let facing = dot(piece.normal, to_eye);
        if facing <= 0.0 {
            continue;
        }
        // Screen positions; skip pieces reaching behind the eye.
        let screen: Option<Vec<[f64; 3]>> = piece
            .poly
            .iter()
            .map(|c| {
                let d = sub(*c, view.eye);
                let z = dot(d, view.forward);
                (z > 1e-6).then(|| {
                    let x = dot(d, view.right) * view.focal / (z * aspect);
                    let y = dot(d, view.up) * view.focal / z;
                    [(x + 1.0) * 0.5 * w as f64, (1.0 - y) * 0.5 * h as f64, z]
                })
            })
            .collect();
        let Some(screen) = screen else {
            continue;
        };
        let colour = match owner.and_then(|m| patches.get(m as usize).map(|p| (m, p))) {
            None => UNOWNED,
            Some((m, p)) => {
                // Albedo lit by a headlight so orientation reads, each patch
                // a little lighter or darker (hashed) so regions show.
                let tint = 0.8 + 0.2 * ((m.wrapping_mul(2_654_435_761) >> 24) as f64 / 255.0);
                let shade = (0.35 + 0.65 * facing) * tint;
                let emissive = p.emission.iter().any(|&e| e > 0.0);
                std::array::from_fn(|c| {
                    let linear = if emissive { tint } else { p.albedo[c] * shade };
                    (255.0 * linear.clamp(0.0, 1.0).powf(1.0 / 2.2)).round() as u8
                })
            }
        };
        for k in 1..screen.len().saturating_sub(1) {
            fill_triangle(
                &mut img,
                &mut depth,
                [screen[0], screen[k], screen[k + 1]],
                colour,
            );
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
