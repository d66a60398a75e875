//! A bake as the run time sees it: the file read and validated once, the
//! reordering applied once at load, so that every per-frame quantity lives
//! in matrix order and no frame permutes anything. Patches carry their
//! shape and frame in f32; the matrix stays compressed (decode-only codec);
//! the mesh map indexes patches in matrix order. Errors are load errors
//! naming the file and the section.

use super::codec::{CodecDataError, Encoded};
use super::near_field::NearField;
use super::records::{BakeInfo, OptionsRecord, INFO_RECORD_VERSION, OPTIONS_RECORD_VERSION};
use super::surface::{PatchSamples, SurfaceMap};
use super::{read, tag, tag_name, BakeFile, BakeFileError, SceneHash};
use radiosity_core::patch::{Direction, Patch};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Why a bake file cannot be run.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    #[error(transparent)]
    File(#[from] BakeFileError),
    #[error("{file}: {source}")]
    Codec {
        file: String,
        #[source]
        source: CodecDataError,
    },
    #[error("{file}: section {tag} ({what}): {detail}")]
    Record {
        file: String,
        tag: String,
        what: &'static str,
        detail: String,
    },
}

/// One patch in matrix order, in f32, with its frame (the square of its
/// area in its plane, [`Patch::frame`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct BakedPatch {
    pub centre: [f32; 3],
    pub normal: [f32; 3],
    pub area: f32,
    pub albedo: [f32; 3],
    pub emission: [f32; 3],
    /// The facing direction (the normal's dominant signed axis).
    pub direction: Direction,
    /// In-plane unit axes and half side of the patch's square.
    pub u: [f32; 3],
    pub v: [f32; 3],
    pub half: f32,
}

/// A loaded bake.
#[derive(Clone, Debug)]
pub struct Baked {
    /// Where it came from, for messages.
    pub file: String,
    /// The patches in matrix order: row and column `i` of [`Baked::matrix`]
    /// are patch `i`.
    pub patches: Vec<BakedPatch>,
    /// The compressed transfer matrix (per colour channel), decode-only.
    pub matrix: Encoded,
    /// `order[i]` is patch `i`'s index in the file's (voxelizer's) order.
    pub order: Vec<u32>,
    /// Per mesh vertex, up to four (patch in matrix order, weight) pairs.
    pub mesh_map: Vec<[(u32, f32); 4]>,
    /// The per-pixel surface map, patches in matrix order.
    pub surface_map: SurfaceMap,
    /// The patches' sample points, in matrix order.
    pub samples: PatchSamples,
    /// The near-field correction, in matrix order (empty for a bake made
    /// without it).
    pub near_field: NearField,
    /// The patches' sky visibility, in matrix order (empty for a bake made
    /// without it: a sky then lights nothing).
    pub sky: crate::sky::SkyVisibility,
    /// The irradiance probes, their patches in matrix order (none when
    /// the bake has no `PROB` section).
    pub probes: crate::probes::Probes,
    pub options: OptionsRecord,
    pub info: BakeInfo,
    pub scene_hash: SceneHash,
}

impl Baked {
    /// Reads, validates and loads the bake file at `path`.
    pub fn load(path: &Path) -> Result<Baked, LoadError> {
        let file = read(path)?;
        Baked::from_file(&file, &path.display().to_string())
    }

    /// Loads an already parsed file; `name` names it in messages
    /// ([`super::IN_MEMORY`] for bytes without a file).
    pub fn from_file(bf: &BakeFile, name: &str) -> Result<Baked, LoadError> {
        let record = |t: [u8; 4], detail: String| LoadError::Record {
            file: name.to_string(),
            tag: tag_name(t),
            what: super::section_what(t),
            detail,
        };
        let options: OptionsRecord = serde_json::from_str(&bf.options_json)
            .map_err(|e| record(tag::OPTIONS, format!("not an options record: {e}")))?;
        if options.record_version != OPTIONS_RECORD_VERSION {
            return Err(record(
                tag::OPTIONS,
                format!(
                    "record version {} (this build reads {OPTIONS_RECORD_VERSION})",
                    options.record_version
                ),
            ));
        }
        let info: BakeInfo = serde_json::from_str(&bf.info_json)
            .map_err(|e| record(tag::INFO, format!("not a bake report: {e}")))?;
        if info.record_version != INFO_RECORD_VERSION {
            return Err(record(
                tag::INFO,
                format!(
                    "record version {} (this build reads {INFO_RECORD_VERSION})",
                    info.record_version
                ),
            ));
        }
        let matrix = Encoded::from_blob(&bf.codec).map_err(|source| LoadError::Codec {
            file: name.to_string(),
            source,
        })?;
        // The container validated the permutation; patch `i` in matrix
        // order is file patch `order[i]`.
        let order = bf.permutation.clone();
        let mut new_of = vec![0u32; order.len()];
        for (new, &old) in order.iter().enumerate() {
            new_of[old as usize] = new as u32;
        }
        let patches = order
            .iter()
            .map(|&old| {
                let r = &bf.patches[old as usize];
                let p = Patch {
                    centre: r.centre.map(f64::from),
                    normal: r.normal.map(f64::from),
                    area: r.area as f64,
                    albedo: r.albedo.map(f64::from),
                    emission: r.emission.map(f64::from),
                    voxel: [0; 3],
                    direction: Direction::dominant(r.normal.map(f64::from)),
                };
                let f = p.frame();
                BakedPatch {
                    centre: r.centre,
                    normal: r.normal,
                    area: r.area,
                    albedo: r.albedo,
                    emission: r.emission,
                    direction: p.direction,
                    u: f.u.map(|x| x as f32),
                    v: f.v.map(|x| x as f32),
                    half: f.half as f32,
                }
            })
            .collect();
        let mesh_map = bf
            .mesh_map
            .iter()
            .map(|row| {
                row.map(|(p, w)| {
                    if w > 0.0 {
                        (new_of[p as usize], w)
                    } else {
                        (0, 0.0)
                    }
                })
            })
            .collect();
        if bf.surface_map.triangles() as u64 != info.triangles {
            return Err(record(
                tag::SURFACE_MAP,
                format!(
                    "maps {} triangles, the bake report says the scene has {}",
                    bf.surface_map.triangles(),
                    info.triangles
                ),
            ));
        }
        Ok(Baked {
            file: name.to_string(),
            surface_map: bf.surface_map.renumbered(&order, &new_of),
            samples: bf.samples.reordered(&order),
            near_field: bf.near_field.reordered(&order, &new_of),
            sky: bf.sky.reordered(&order),
            probes: bf.probes.renumbered(&new_of),
            patches,
            matrix,
            order,
            mesh_map,
            options,
            info,
            scene_hash: bf.scene_hash,
        })
    }

    /// Interpolates per-patch values (matrix order) at every mesh vertex
    /// through the mesh map: the CPU reference of run-time step 4 at
    /// vertices.
    pub fn interpolate_vertices(&self, values: &[[f32; 3]]) -> Vec<[f32; 3]> {
        interpolate(&self.mesh_map, values)
    }
}

/// `Σ w · values[p]` per row of a mesh map.
pub fn interpolate(map: &[[(u32, f32); 4]], values: &[[f32; 3]]) -> Vec<[f32; 3]> {
    map.iter()
        .map(|row| {
            let mut h = [0.0f32; 3];
            for &(p, w) in row {
                if w > 0.0 {
                    for (c, hc) in h.iter_mut().enumerate() {
                        *hc += w * values[p as usize][c];
                    }
                }
            }
            h
        })
        .collect()
}

/// The scene path to store in a bake written to `bake`: relative to the
/// bake file's directory when both resolve (so a bake and its scene move
/// together), else as given.
pub fn stored_scene_path(bake: &Path, scene: &Path) -> String {
    let dir = bake.parent().filter(|d| !d.as_os_str().is_empty());
    let dir = dir.map_or_else(|| PathBuf::from("."), Path::to_path_buf);
    match (dir.canonicalize(), scene.canonicalize()) {
        (Ok(d), Ok(s)) => relative(&d, &s).display().to_string(),
        _ => scene.display().to_string(),
    }
}

/// Where the scene stored in a bake file at `bake` lies: a relative path is
/// relative to the bake file's directory. `dir/../scene.obj` (a bake in the
/// cache next to its scene) is shortened to `scene.obj`'s own directory
/// where both name the same file (not across a symbolic link), so that
/// messages name the scene as the user does.
pub fn resolve_scene_path(bake: &Path, stored: &str) -> PathBuf {
    let p = PathBuf::from(stored);
    if p.is_absolute() {
        return p;
    }
    let joined = match bake.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.join(p),
        _ => p,
    };
    let mut short = PathBuf::new();
    for c in joined.components() {
        match c {
            std::path::Component::ParentDir
                if matches!(
                    short.components().next_back(),
                    Some(std::path::Component::Normal(_))
                ) =>
            {
                short.pop();
            }
            std::path::Component::CurDir => {}
            c => short.push(c.as_os_str()),
        }
    }
    match (joined.canonicalize(), short.canonicalize()) {
        (Ok(a), Ok(b)) if a == b && short != joined => short,
        _ => joined,
    }
}

/// `to` relative to `from` (both absolute and canonical).
fn relative(from: &Path, to: &Path) -> PathBuf {
    let a: Vec<_> = from.components().collect();
    let b: Vec<_> = to.components().collect();
    let common = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let mut out = PathBuf::new();
    for _ in common..a.len() {
        out.push("..");
    }
    for c in &b[common..] {
        out.push(c.as_os_str());
    }
    out
}

/// What `radiosity info` prints about a bake file.
#[derive(Clone, Debug, Serialize)]
pub struct FileSummary {
    pub file: PathBuf,
    pub bytes_file: u64,
    pub format_version: u32,
    pub patches: u64,
    /// How evenly the patches share the area.
    pub spread: radiosity_core::patch::AreaSpread,
    /// `k` or `"inf"`.
    pub bounces: super::records::BouncesRecord,
    pub reorder: String,
    pub codec: String,
    /// The smallest and largest column scale ([`Encoded::col_scale`]),
    /// `None` for a matrix without them.
    pub column_scales: Option<(f32, f32)>,
    pub bytes_per_entry: f64,
    pub bytes_dense: u64,
    pub bytes_sparse: u64,
    pub bytes_index: u64,
    pub zero_tile_fraction: f64,
    /// Relative RMS error of `H` measured at bake time.
    pub h_error: Option<f64>,
    pub error_lights: u64,
    pub mesh_map_vertices: u64,
    /// The sky visibility's stored cells and its section's bytes (`None`:
    /// the bake has none, and a sky lights nothing).
    pub sky: Option<(u64, u64)>,
    /// The bytes of the near-field section's open sky per cell
    /// ([`crate::near_field`], "The sky"; `None`: not stored, and the
    /// near-field correction leaves the sky alone).
    pub near_field_sky: Option<u64>,
    /// The bytes of the near-field section's counts by the receiver's cell
    /// ([`crate::near_field`], "At the receiver"; `None`: not stored, and
    /// `H` is one value per patch).
    pub near_field_receiver: Option<u64>,
    /// The irradiance probes: probes, used ones, entries (patch, sky,
    /// emission together) and the section's bytes (`None`: no probes).
    pub probes: Option<(u64, u64, u64, u64)>,
    /// The scene as stored, and where it was looked for.
    pub scene: String,
    pub scene_path: PathBuf,
    /// Whether the scene files still hash as they did at bake time:
    /// `"unchanged"`, `"changed since the bake: obj, mtl"`, or why it could
    /// not be checked.
    pub scene_status: String,
    pub options: OptionsRecord,
    pub info: BakeInfo,
}

/// Reads, validates and summarises the bake file at `path`; the scene is
/// looked for relative to the bake file and its hash compared.
pub fn describe(path: &Path) -> Result<FileSummary, LoadError> {
    let bytes_file = std::fs::metadata(path)
        .map_err(|source| BakeFileError::Read {
            path: path.to_path_buf(),
            source,
        })?
        .len();
    let b = Baked::load(path)?;
    let scene_path = resolve_scene_path(path, &b.info.scene);
    let scene_status = match radiosity_core::scene::load(&scene_path) {
        Err(e) => format!("not checked: {e}"),
        Ok(s) => match SceneHash::of_scene(&s) {
            Err(e) => format!("not checked: {e}"),
            Ok(h) => {
                let d = b.scene_hash.differences(&h);
                if d.is_empty() {
                    "unchanged".into()
                } else {
                    format!("changed since the bake: {}", d.join(", "))
                }
            }
        },
    };
    let e = &b.matrix;
    Ok(FileSummary {
        file: path.to_path_buf(),
        bytes_file,
        format_version: super::FORMAT_VERSION,
        patches: b.patches.len() as u64,
        spread: radiosity_core::patch::AreaSpread::of(
            b.patches.iter().map(|p| f64::from(p.area)),
            b.options.voxel_size,
        ),
        bounces: b.options.bounces,
        reorder: b.options.reorder.clone(),
        codec: e.kind.name(),
        column_scales: (!e.col_scale.is_empty()).then(|| {
            e.col_scale
                .iter()
                .fold((f32::MAX, 0.0f32), |(lo, hi), &v| (lo.min(v), hi.max(v)))
        }),
        bytes_per_entry: e.bytes_per_entry(),
        bytes_dense: e.bytes_dense() as u64,
        bytes_sparse: e.bytes_sparse() as u64,
        bytes_index: e.bytes_index() as u64,
        zero_tile_fraction: e.zero_tile_fraction(),
        h_error: b.info.h_error,
        error_lights: b.options.error_lights,
        mesh_map_vertices: b.mesh_map.len() as u64,
        sky: (!b.sky.is_empty())
            .then(|| (b.sky.values.len() as u64, b.sky.to_bytes().len() as u64)),
        near_field_sky: (!b.near_field.sky.is_empty())
            .then(|| (b.near_field.sky.len() * 4 * crate::surface::SAMPLES_PER_PATCH) as u64),
        probes: (!b.probes.is_empty()).then(|| {
            let p = &b.probes;
            (
                p.len() as u64,
                p.states.iter().filter(|s| s.is_used()).count() as u64,
                (p.patches.len() + p.sky_cells.len() + p.emitters.len()) as u64,
                p.to_bytes().len() as u64,
            )
        }),
        near_field_receiver: (!b.near_field.cast.is_empty()).then(|| {
            ((b.near_field.links.len() + b.near_field.cast.len())
                * 2
                * crate::surface::SAMPLES_PER_PATCH) as u64
        }),
        scene: b.info.scene.clone(),
        scene_path,
        scene_status,
        options: b.options.clone(),
        info: b.info.clone(),
    })
}

impl std::fmt::Display for FileSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "{}: radiosity bake, format v{}, {} bytes",
            self.file.display(),
            self.format_version,
            self.bytes_file
        )?;
        writeln!(
            f,
            "scene: {} (looked for at {}: {})",
            self.scene,
            self.scene_path.display(),
            self.scene_status
        )?;
        writeln!(
            f,
            "patches: {}; voxel size {}; bounces: {}; reorder: {}; {}",
            self.patches,
            self.options.voxel_size,
            self.bounces,
            self.reorder,
            if self.options.two_sided {
                "two-sided (patches on both sides of every surface)"
            } else {
                "one-sided"
            }
        )?;
        writeln!(f, "{}", self.spread)?;
        if !self.options.two_sided {
            writeln!(
                f,
                "winding: {} faces given a back side (seen from both sides; the bake's \
                 summary names their materials)",
                self.options.twinned.len()
            )?;
        }
        let entries = (self.patches * self.patches).max(1) as f64;
        writeln!(
            f,
            "codec: {} ({}); bytes per matrix entry {:.4} (dense {:.4}, sparse {:.4}, index \
             {:.4}); zero tiles skipped {:.1} %",
            self.codec,
            self.options.codec_choice,
            self.bytes_per_entry,
            self.bytes_dense as f64 / entries,
            self.bytes_sparse as f64 / entries,
            self.bytes_index as f64 / entries,
            100.0 * self.zero_tile_fraction
        )?;
        match self.sky {
            Some((cells, bytes)) => writeln!(
                f,
                "sky visibility: {cells} sky cells stored ({:.1} per patch), {bytes} bytes \
                 ({:.2} % of the file)",
                cells as f64 / self.patches.max(1) as f64,
                100.0 * bytes as f64 / self.bytes_file.max(1) as f64
            )?,
            None => writeln!(
                f,
                "sky visibility: none (a sky lights nothing: bake again with ray form factors)"
            )?,
        }
        match self.probes {
            Some((probes, used, entries, bytes)) => writeln!(
                f,
                "irradiance probes: {probes} ({used} used, the others in solids), {entries} \
                 entries, {bytes} bytes ({:.2} % of the file)",
                100.0 * bytes as f64 / self.bytes_file.max(1) as f64
            )?,
            None => writeln!(
                f,
                "irradiance probes: none (moving objects get no indirect light: bake again)"
            )?,
        }
        if let Some(bytes) = self.near_field_receiver {
            writeln!(
                f,
                "the near field at the receivers' cells: {bytes} bytes ({:.2} % of the file)",
                100.0 * bytes as f64 / self.bytes_file.max(1) as f64
            )?;
        }
        if let Some(bytes) = self.near_field_sky {
            writeln!(
                f,
                "the sky at the near field's cells: {bytes} bytes ({:.2} % of the file)",
                100.0 * bytes as f64 / self.bytes_file.max(1) as f64
            )?;
        } else if self.sky.is_some() {
            writeln!(
                f,
                "the sky at the near field's cells: none (the near-field correction leaves the \
                 sky alone: bake again with the near field)"
            )?;
        }
        match self.column_scales {
            Some((lo, hi)) => writeln!(
                f,
                "column scales (relative patch areas): {lo:.3e} to {hi:.3e}"
            )?,
            None => writeln!(f, "column scales: none")?,
        }
        match self.h_error {
            Some(e) => writeln!(
                f,
                "compression error at bake time: {:.3} % relative RMS of H over {} random lights",
                100.0 * e,
                self.error_lights
            )?,
            None => writeln!(f, "compression error: not measured at bake time")?,
        }
        writeln!(
            f,
            "mesh map: {} vertices ({} fallbacks, {} unmapped)",
            self.mesh_map_vertices, self.info.mesh_map_fallbacks, self.info.mesh_map_unmapped
        )
    }
}
