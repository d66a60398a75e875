//! Image errors of the sweep against Mitsuba 3 (docs/design.md section 3,
//! measure 4): the run time's final and indirect views of a scene's camera
//! and lights against the path tracer's, which include everything the
//! patches simplify (voxels, the surface map, bounces, the codec).
//!
//! The references come from `scripts/mitsuba-reference` (bounces `∞`,
//! cached by a hash of the exported scene), run once per scene into
//! `<references>/<scene>/` when not already there. Our pixels average
//! several pixel-centre rays to match Mitsuba's box filter: `DIRECT_SS²`
//! for the direct view (the emitter's sharp, bright edges dominate it),
//! `INDIRECT_SS²` for the smooth indirect view; final = direct + indirect
//! exactly (`ρ/π (D + H) + Le`), so the direct image is rendered once per
//! scene. Errors are noise-corrected relative RMS
//! ([`crate::mitsuba::reference`]).

use crate::core::scene_config::SceneConfig;
use crate::mitsuba::reference::downsample;
use crate::mitsuba::{image_error, ImageError, Reference};
use crate::runtime::render::{render, View};
use crate::runtime::texture::Albedo;
use crate::runtime::tonemap::{auto_exposure, to_srgb8};
use crate::runtime::Runtime;
use anyhow::Context;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Rays per pixel side for the direct view.
const DIRECT_SS: usize = 8;
/// Rays per pixel side for the indirect view.
const INDIRECT_SS: usize = 4;

/// How the sweep gets its references.
#[derive(Clone, Debug)]
pub struct ReferenceOptions {
    /// Where each scene's reference lives (`<dir>/<scene stem>/`).
    pub dir: PathBuf,
    pub width: usize,
    pub height: usize,
    /// Samples per pixel of a reference made by the sweep.
    pub spp: u32,
}

/// A scene's reference and our direct image at its size.
pub struct SceneImages {
    pub reference: Reference,
    pub reference_dir: PathBuf,
    /// The albedo textures, decoded once per scene (not per point).
    albedo: Option<Albedo>,
    direct: Option<Vec<[f32; 3]>>,
}

/// The reference of `obj` (with `camera_lights`), made by the script when
/// `<dir>/<stem>/meta.json` does not exist yet.
pub fn reference(
    obj: &Path,
    camera_lights: &Path,
    options: &ReferenceOptions,
    progress: &mut dyn FnMut(&str),
) -> anyhow::Result<SceneImages> {
    let dir = options.dir.join(scene_label(obj, camera_lights));
    if !dir.join("meta.json").exists() {
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/mitsuba-reference");
        progress(&format!(
            "Mitsuba 3 reference of {} ({} × {}, {} spp): {}",
            obj.display(),
            options.width,
            options.height,
            options.spp,
            script.display()
        ));
        let exe = std::env::current_exe().context("locating this program for the script")?;
        let status = Command::new(&script)
            .arg(obj)
            .arg("--camera-lights")
            .arg(camera_lights)
            .arg("-o")
            .arg(&dir)
            .args(["--width", &options.width.to_string()])
            .args(["--height", &options.height.to_string()])
            .args(["--spp", &options.spp.to_string()])
            .env("RADIOSITY", exe)
            .status()
            .with_context(|| format!("running {}", script.display()))?;
        anyhow::ensure!(
            status.success(),
            "{} failed ({status}) for {}",
            script.display(),
            obj.display()
        );
    }
    let reference = Reference::load(&dir)?;
    anyhow::ensure!(
        reference.final_.is_some(),
        "{}: the reference has no final image (made with --views direct)",
        dir.display()
    );
    Ok(SceneImages {
        reference,
        reference_dir: dir,
        albedo: None,
        direct: None,
    })
}

/// A scene's name in the benchmarks' reports, reference folders and image
/// files: the OBJ's stem, and the camera-and-lights file's after a `+`
/// when that is not the OBJ's own `STEM.json` — so that one scene under two
/// lightings (Sponza's sun, Sponza's sun and sky) never shares a reference.
pub fn scene_label(obj: &Path, camera_lights: &Path) -> String {
    let stem = |p: &Path| {
        p.file_stem()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned()
    };
    let (o, l) = (stem(obj), stem(camera_lights));
    if o == l {
        o
    } else {
        format!("{o}+{l}")
    }
}

/// Errors of one point's final and indirect views (the runtime's last
/// frame, `config`'s camera); with `png`, also writes the four images side
/// by side there ([`comparison_png`]).
pub fn errors(
    images: &mut SceneImages,
    rt: &Runtime,
    config: &SceneConfig,
    png: Option<&Path>,
) -> anyhow::Result<(ImageError, ImageError)> {
    let (w, h) = (images.reference.width, images.reference.height);
    let albedo = images.albedo.get_or_insert_with(|| Albedo::new(&rt.scene));
    let view = |v: View, ss: usize| {
        let (img, _) = render(rt, config, v, w * ss, h * ss, albedo);
        downsample(&img.radiance, w * ss, h * ss, ss)
    };
    let direct = images
        .direct
        .get_or_insert_with(|| view(View::Direct, DIRECT_SS));
    let indirect = view(View::Indirect, INDIRECT_SS);
    let fin: Vec<[f32; 3]> = direct
        .iter()
        .zip(&indirect)
        .map(|(d, i)| std::array::from_fn(|c| d[c] + i[c]))
        .collect();
    let r = &images.reference;
    let (Some(final_), Some(indirect_ref)) = (&r.final_, &r.indirect) else {
        anyhow::bail!("{}: no final image", images.reference_dir.display());
    };
    if let Some(path) = png {
        let mean = |h: &[Vec<[f32; 3]>; 2]| -> Vec<[f32; 3]> {
            h[0].iter()
                .zip(&h[1])
                .map(|(a, b)| std::array::from_fn(|c| 0.5 * (a[c] + b[c])))
                .collect()
        };
        comparison_png(
            path,
            w,
            h,
            [&fin, &mean(final_), &indirect, &mean(indirect_ref)],
        )?;
    }
    Ok((
        image_error(&fin, final_),
        image_error(&indirect, indirect_ref),
    ))
}

/// Writes a 2 × 2 grid (`w × h` each): ours and Mitsuba's final view on
/// top, ours and Mitsuba's indirect view below; each row tone mapped with
/// the exposure of Mitsuba's image (runtime/tonemap.rs), so brightness
/// differences show.
pub fn comparison_png(
    path: &Path,
    w: usize,
    h: usize,
    [ours_final, ref_final, ours_indirect, ref_indirect]: [&[[f32; 3]]; 4],
) -> anyhow::Result<()> {
    let mut rgb = vec![0u8; 4 * w * h * 3];
    let rows = [
        (ours_final, ref_final, auto_exposure(ref_final.iter())),
        (
            ours_indirect,
            ref_indirect,
            auto_exposure(ref_indirect.iter()),
        ),
    ];
    for (row, (ours, reference, exposure)) in rows.into_iter().enumerate() {
        for (col, img) in [ours, reference].into_iter().enumerate() {
            for y in 0..h {
                for x in 0..w {
                    let p = to_srgb8(img[y * w + x], exposure);
                    let (gy, gx) = (row * h + y, col * w + x);
                    rgb[(gy * 2 * w + gx) * 3..][..3].copy_from_slice(&p);
                }
            }
        }
    }
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    image::RgbImage::from_raw(2 * w as u32, 2 * h as u32, rgb)
        .context("image size")?
        .save(path)
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One scene under two lightings gets two names (two reference
    /// folders); a scene with its own `STEM.json` keeps its stem.
    #[test]
    fn a_scene_under_another_lighting_has_its_own_label() {
        let obj = Path::new("elsewhere/sponza.obj");
        assert_eq!(scene_label(obj, Path::new("x/sponza.json")), "sponza");
        assert_eq!(
            scene_label(obj, Path::new("x/sponza_noon.json")),
            "sponza+sponza_noon"
        );
    }
}
