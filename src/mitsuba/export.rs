//! The export: a scene with its camera and lights written as a
//! Mitsuba 3 scene (XML, one OBJ per material, one linear PFM texture per
//! textured material), for the independent reference images of
//! `scripts/mitsuba-reference` (docs/design.md section 3, measure 4).
//!
//! Everything is translated from the one definition each quantity has in
//! this project, so that the path tracer and the run time see the same
//! scene:
//! - geometry: the loaded scene's triangles (after the loader's repairs),
//!   flat-shaded as the run time shades them (no vertex normals written);
//! - albedo: the run time's `ρ(x)` ([`crate::runtime::texture::Albedo`]):
//!   `Kd` for an untextured material, `Kd · texture(uv)` clamped to
//!   [`ALBEDO_MAX`] for a textured one, written as a linear PFM so that
//!   Mitsuba reads it without any colour conversion (`raw`);
//! - emission: `Ke` is radiant exitance, so Mitsuba's `area` emitter gets the
//!   radiance `Ke / π`, times the run-time scale of the material
//!   ([`SceneConfig::emission`]); an emitter emits on its front side only,
//!   as in the bake;
//! - lights ([`crate::core::light`]): `directional` with `irradiance`,
//!   `point` with `intensity` (W/sr), `spot` with `intensity`,
//!   `cutoff_angle` = cone and `beam_width` = beam (the profile the run
//!   time copies from Mitsuba's `spot`);
//! - camera: `perspective` with the vertical field of view, a box pixel
//!   filter (each pixel the mean over its area, which the run time's
//!   supersampled reference images match);
//! - sky ([`crate::core::sky`]): a uniform sky is a `constant` emitter,
//!   any other an `envmap` of `sky.pfm`, our sky's radiance sampled at the
//!   texel centres of Mitsuba's latitude-longitude map (`u = atan2(x, −z)/2π`,
//!   `v = acos(y)/π`, the top row the zenith: the convention
//!   [`crate::core::sky::envmap`] reads maps in), with the map's rotation
//!   and intensity applied; a sun and sky's sun is a `directional`
//!   emitter like the file's own lights. Mitsuba's own `sunsky` is not
//!   used: it is Hosek–Wilkie's sky, and what is compared is the transport
//!   under one sky, not two sky models. `lights_only.xml` hides directly
//!   seen emitters, so that the sky behind the scene counts once in the
//!   direct view (in `Le`).
//!
//! Two scene files are written: `scene.xml` (everything) and
//! `lights_only.xml` (no area emitters): the run time's direct view
//! `ρ/π · D + Le` is Mitsuba's `scene.xml` at `max_depth = 1` (`Le`) plus
//! `lights_only.xml` at `max_depth = 2` (`ρ/π · D`), and its indirect view
//! is the final image minus that direct view. `max_depth`, `spp` and `seed`
//! are parameters (`$max_depth`, `$spp`, `$seed`) of both files.

use crate::core::scene::{Scene, Wrap, ALBEDO_MAX};
use crate::core::scene_config::{Light, SceneConfig};
use crate::core::sky::{envmap, Sky};
use crate::runtime::texture::Texture;
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// An error writing the Mitsuba export.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// A file could not be written.
    #[error("cannot write {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A material's texture could not be read.
    #[error("material `{material}`: {source}")]
    Texture {
        material: String,
        #[source]
        source: crate::core::error::ImageError,
    },
    /// The image size is zero or too large.
    #[error("image size {width} x {height}: both must be 1..=16384")]
    ImageSize { width: usize, height: usize },
}

/// What [`export`] writes besides the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExportOptions {
    /// Image width in pixels.
    pub width: usize,
    /// Image height in pixels.
    pub height: usize,
    /// Whether surfaces reflect on both sides (a two-sided bake); emitters
    /// still emit on their front only.
    pub two_sided: bool,
}

/// What [`export`] wrote.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ExportSummary {
    /// One mesh per material that has triangles.
    pub meshes: usize,
    /// Textured materials (a PFM each).
    pub textures: usize,
    /// Materials with a non-zero emission after scaling.
    pub emitters: usize,
    /// Lights of the configuration.
    pub lights: usize,
}

/// Every file [`export`] of `scene` writes into `dir` (whatever the
/// materials it meshes): the two scene files, a mesh and a texture per
/// material.
pub fn files(scene: &Scene, dir: &Path) -> Vec<std::path::PathBuf> {
    let mut out = vec![
        dir.join("scene.xml"),
        dir.join("lights_only.xml"),
        dir.join("sky.pfm"),
    ];
    for m in 0..scene.materials.len() {
        out.push(dir.join(format!("meshes/m{m}.obj")));
        out.push(dir.join(format!("textures/m{m}.pfm")));
    }
    out
}

/// Writes the Mitsuba scene of `scene` with the camera, lights and emission
/// scales of `config` into `dir` (created if needed): `scene.xml`,
/// `lights_only.xml`, `meshes/m<i>.obj`, `textures/m<i>.pfm`.
pub fn export(
    scene: &Scene,
    config: &SceneConfig,
    options: ExportOptions,
    dir: &Path,
) -> Result<ExportSummary, ExportError> {
    let (w, h) = (options.width, options.height);
    if !(1..=16384).contains(&w) || !(1..=16384).contains(&h) {
        return Err(ExportError::ImageSize {
            width: w,
            height: h,
        });
    }
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| ExportError::Io { path, source }
    };
    for sub in ["meshes", "textures"] {
        let d = dir.join(sub);
        std::fs::create_dir_all(&d).map_err(io(&d))?;
    }
    let mut summary = ExportSummary {
        lights: config.frame_lights().len(),
        ..Default::default()
    };
    let mut shapes = String::new();
    let mut emitters = String::new();
    // Triangles by material, in one pass.
    let mut by_material = vec![Vec::new(); scene.materials.len()];
    for (t, &m) in scene.triangle_material.iter().enumerate() {
        by_material[m as usize].push(t);
    }
    for ((m, mat), tris) in scene.materials.iter().enumerate().zip(by_material) {
        if tris.is_empty() {
            continue;
        }
        summary.meshes += 1;
        let mesh = format!("meshes/m{m}.obj");
        let path = dir.join(&mesh);
        std::fs::write(&path, mesh_obj(scene, &tris)).map_err(io(&path))?;
        // The albedo: the run time's ρ(x) (module doc).
        let textured = !scene.texcoords.is_empty() && mat.diffuse_texture.is_some();
        let reflectance = if let (true, Some(tex)) = (textured, &mat.diffuse_texture) {
            let t = Texture::load(tex).map_err(|source| ExportError::Texture {
                material: mat.name.clone(),
                source,
            })?;
            let texels: Vec<[f32; 3]> = t
                .texels
                .iter()
                .map(|p| std::array::from_fn(|c| (mat.kd[c] * p[c]).clamp(0.0, ALBEDO_MAX)))
                .collect();
            let name = format!("textures/m{m}.pfm");
            let path = dir.join(&name);
            crate::runtime::tonemap::write_pfm(&path, t.width, t.height, &texels)
                .map_err(io(&path))?;
            summary.textures += 1;
            // Mitsuba's bitmap has one wrap mode for both axes: the s axis's.
            let wrap = match tex.wrap[0] {
                Wrap::Repeat => "repeat",
                Wrap::MirroredRepeat => "mirror",
                Wrap::ClampToEdge => "clamp",
            };
            format!(
                "<texture type=\"bitmap\" name=\"reflectance\"><string name=\"filename\" \
                 value=\"{name}\"/><boolean name=\"raw\" value=\"true\"/><string \
                 name=\"filter_type\" value=\"bilinear\"/><string name=\"wrap_mode\" \
                 value=\"{wrap}\"/></texture>"
            )
        } else {
            format!("<rgb name=\"reflectance\" value=\"{}\"/>", rgb(mat.albedo))
        };
        let mut bsdf = format!("<bsdf type=\"diffuse\">{reflectance}</bsdf>");
        if options.two_sided {
            bsdf = format!("<bsdf type=\"twosided\">{bsdf}</bsdf>");
        }
        let scale = config.emission.get(&mat.name).copied().unwrap_or(1.0);
        let le = mat.emission.map(|e| scale * e / std::f32::consts::PI);
        let emitter = if le.iter().any(|&v| v > 0.0) {
            summary.emitters += 1;
            format!(
                "\n    <emitter type=\"area\"><rgb name=\"radiance\" value=\"{}\"/></emitter>",
                rgb(le)
            )
        } else {
            String::new()
        };
        let open = format!(
            "  <shape type=\"obj\" id=\"m{m}\">\n    <string name=\"filename\" value=\"{mesh}\"/>\n    \
             <boolean name=\"face_normals\" value=\"true\"/>\n    {bsdf}"
        );
        let _ = writeln!(shapes, "{open}\n  </shape>");
        let _ = writeln!(emitters, "{open}{emitter}\n  </shape>");
    }
    let lights = lights_xml(&config.frame_lights()) + &sky_xml(config.sky.as_ref(), dir)?;
    let sensor = sensor_xml(scene, config, w, h);
    for (name, body) in [("scene.xml", &emitters), ("lights_only.xml", &shapes)] {
        // The sky seen directly counts in `Le` (scene.xml) only.
        let hide = if name == "lights_only.xml" && config.sky.is_some() {
            "<boolean name=\"hide_emitters\" value=\"true\"/>"
        } else {
            ""
        };
        let xml = format!(
            "<?xml version=\"1.0\"?>\n<!-- Written by `radiosity export-mitsuba` from {}. -->\n\
             <scene version=\"3.0.0\">\n  <default name=\"max_depth\" value=\"-1\"/>\n  \
             <default name=\"spp\" value=\"64\"/>\n  <default name=\"seed\" value=\"0\"/>\n  \
             <integrator type=\"path\"><integer name=\"max_depth\" value=\"$max_depth\"/>\
             {hide}</integrator>\n{sensor}{lights}{body}</scene>\n",
            scene.source.display()
        );
        let path = dir.join(name);
        std::fs::write(&path, xml).map_err(io(&path))?;
    }
    Ok(summary)
}

/// The triangles `tris` as an OBJ (positions, texture coordinates when the
/// scene has them), vertices renumbered from 1.
fn mesh_obj(scene: &Scene, tris: &[usize]) -> String {
    let mut index = std::collections::HashMap::new();
    let mut order = Vec::new();
    let mut faces = Vec::with_capacity(tris.len());
    for &t in tris {
        faces.push(scene.triangles[t].map(|v| {
            *index.entry(v).or_insert_with(|| {
                order.push(v as usize);
                order.len()
            })
        }));
    }
    let uv = !scene.texcoords.is_empty();
    let mut s = String::with_capacity(order.len() * 60 + faces.len() * 30);
    for &v in &order {
        let p = scene.positions[v];
        let _ = writeln!(s, "v {:e} {:e} {:e}", p[0], p[1], p[2]);
    }
    if uv {
        for &v in &order {
            let t = scene.texcoords[v];
            let _ = writeln!(s, "vt {:e} {:e}", t[0], t[1]);
        }
    }
    for [a, b, c] in faces {
        if uv {
            let _ = writeln!(s, "f {a}/{a} {b}/{b} {c}/{c}");
        } else {
            let _ = writeln!(s, "f {a} {b} {c}");
        }
    }
    s
}

fn rgb(c: [f32; 3]) -> String {
    format!("{:e}, {:e}, {:e}", c[0], c[1], c[2])
}

fn vec3(name: &str, v: [f32; 3]) -> String {
    format!(
        "<vector name=\"{name}\" x=\"{:e}\" y=\"{:e}\" z=\"{:e}\"/>",
        v[0], v[1], v[2]
    )
}

fn point3(name: &str, v: [f32; 3]) -> String {
    format!(
        "<point name=\"{name}\" x=\"{:e}\" y=\"{:e}\" z=\"{:e}\"/>",
        v[0], v[1], v[2]
    )
}

/// `lookat` attribute text for a frame at `origin` looking at `target`.
fn lookat(origin: [f32; 3], target: [f32; 3], up: [f32; 3]) -> String {
    let f = |v: [f32; 3]| format!("{:e}, {:e}, {:e}", v[0], v[1], v[2]);
    format!(
        "<lookat origin=\"{}\" target=\"{}\" up=\"{}\"/>",
        f(origin),
        f(target),
        f(up)
    )
}

/// The size of the latitude-longitude map a sky is written as: a
/// gradient does not depend on the azimuth (8 columns; 512 rows, 0.35°
/// apart, follow its linear profile to 1e-5 of its range under bilinear
/// lookup); a sun and sky needs the circumsolar brightening (1024 × 512,
/// 0.35° texels); a map keeps its own size.
fn sky_map_size(sky: &Sky) -> (usize, usize) {
    match sky {
        Sky::Gradient { .. } | Sky::Uniform { .. } => (8, 512),
        Sky::Sunsky { .. } => (1024, 512),
        Sky::Envmap { map, .. } => map.as_ref().map_or((8, 4), |m| (m.0.width, m.0.height)),
    }
}

/// The sky's emitter (module doc), writing `sky.pfm` into `dir` for any
/// but a uniform sky: its radiance at each texel's centre in Mitsuba's
/// latitude-longitude convention ([`crate::core::sky::envmap`]), the
/// map's rotation and intensity applied. A sun and sky's sun is a
/// `directional` emitter among the lights
/// ([`crate::core::scene_config::SceneConfig::frame_lights`]).
fn sky_xml(sky: Option<&Sky>, dir: &Path) -> Result<String, ExportError> {
    Ok(match sky {
        None => String::new(),
        Some(Sky::Uniform { radiance }) => format!(
            "  <emitter type=\"constant\"><rgb name=\"radiance\" value=\"{}\"/></emitter>\n",
            rgb(*radiance)
        ),
        Some(sky) => {
            let (cols, rows) = sky_map_size(sky);
            let prepared = sky.prepared();
            let texels: Vec<[f32; 3]> = (0..rows * cols)
                .into_par_iter()
                .map(|k| {
                    let (u, v) = (
                        ((k % cols) as f64 + 0.5) / cols as f64,
                        ((k / cols) as f64 + 0.5) / rows as f64,
                    );
                    prepared.radiance(envmap::direction(u, v)).map(|v| v as f32)
                })
                .collect();
            let path = dir.join("sky.pfm");
            crate::runtime::tonemap::write_pfm(&path, cols, rows, &texels).map_err(|source| {
                ExportError::Io {
                    path: path.clone(),
                    source,
                }
            })?;
            "  <emitter type=\"envmap\"><string name=\"filename\" value=\"sky.pfm\"/></emitter>\n"
                .to_string()
        }
    })
}

/// The lights, each translated as the module doc says.
fn lights_xml(lights: &[Light]) -> String {
    let mut s = String::new();
    for l in lights {
        let _ = match *l {
            Light::Directional {
                direction,
                irradiance,
            } => writeln!(
                s,
                "  <emitter type=\"directional\">{}<rgb name=\"irradiance\" value=\"{}\"/></emitter>",
                vec3("direction", direction),
                rgb(irradiance)
            ),
            Light::Point {
                position,
                intensity,
            } => writeln!(
                s,
                "  <emitter type=\"point\">{}<rgb name=\"intensity\" value=\"{}\"/></emitter>",
                point3("position", position),
                rgb(intensity)
            ),
            Light::Spot {
                position,
                direction,
                intensity,
                cone_angle_deg,
                beam_angle_deg,
            } => {
                // Any up vector not parallel to the axis: the profile is
                // symmetric about it.
                let len = crate::core::math::norm(direction.map(f64::from)) as f32;
                let up = if direction[1].abs() > 0.9 * len {
                    [1.0, 0.0, 0.0]
                } else {
                    [0.0, 1.0, 0.0]
                };
                let target = std::array::from_fn(|k| position[k] + direction[k]);
                writeln!(
                    s,
                    "  <emitter type=\"spot\"><transform name=\"to_world\">{}</transform>\
                     <rgb name=\"intensity\" value=\"{}\"/><float name=\"cutoff_angle\" \
                     value=\"{:e}\"/><float name=\"beam_width\" value=\"{:e}\"/></emitter>",
                    lookat(position, target, up),
                    rgb(intensity),
                    cone_angle_deg,
                    beam_angle_deg
                )
            }
        };
    }
    s
}

/// The camera: perspective, vertical field of view, clip planes from the
/// scene's extent (Mitsuba's defaults, 0.01 and 10,000, would cut scenes in
/// millimetres or kilometres), a box filter, linear RGB.
fn sensor_xml(scene: &Scene, config: &SceneConfig, w: usize, h: usize) -> String {
    let c = &config.camera;
    let (lo, hi) = scene.bounds();
    let far = (0..8)
        .map(|i| {
            let corner: [f64; 3] =
                std::array::from_fn(|k| (if i >> k & 1 == 1 { hi[k] } else { lo[k] }) as f64);
            crate::core::math::norm(std::array::from_fn(|k| corner[k] - c.position[k] as f64))
        })
        .fold(0.0f64, f64::max);
    let far = (2.0 * far).max(1e-6);
    let near = far * 1e-4;
    format!(
        "  <sensor type=\"perspective\">\n    <float name=\"fov\" value=\"{:e}\"/>\n    \
         <string name=\"fov_axis\" value=\"y\"/>\n    <float name=\"near_clip\" value=\"{near:e}\"/>\n    \
         <float name=\"far_clip\" value=\"{far:e}\"/>\n    <transform name=\"to_world\">{}</transform>\n    \
         <sampler type=\"independent\"><integer name=\"sample_count\" value=\"$spp\"/>\
         <integer name=\"seed\" value=\"$seed\"/></sampler>\n    <film type=\"hdrfilm\">\
         <integer name=\"width\" value=\"{w}\"/><integer name=\"height\" value=\"{h}\"/>\
         <string name=\"pixel_format\" value=\"rgb\"/><rfilter type=\"box\"/></film>\n  </sensor>\n",
        c.fov_y_deg,
        lookat(c.position, c.target, c.up)
    )
}
