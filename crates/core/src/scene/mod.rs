//! Scene loading: OBJ + MTL through `tobj` (here) and glTF 2.0 through the
//! `gltf` crate ([`gltf`]), triangulated, validated and repaired with every
//! repair counted (docs/design.md section 4: nothing is silently clamped or
//! dropped). Both formats end in one [`Scene`] and one set of checks.
//!
//! [`load`] reads the OBJ with `tobj` (triangulated, single index, points
//! and lines ignored), merges every model into one vertex array and gives
//! each triangle a material. The albedo of a material is `Kd` times the
//! linear-space mean of its `map_Kd` texture (decoded as sRGB, converted to
//! linear per pixel with the exact piecewise EOTF, then averaged), clamped
//! to [`ALBEDO_MAX`]; the emission is `Ke`. Bad input is an error that names
//! the file and the line: malformed records, non-finite or huge coordinates
//! ([`MAX_ABS_COORDINATE`]), face indices out of range, negative or
//! non-finite `Kd`/`Ke`. Recoverable problems are repaired and counted in
//! [`Repairs`] with a human-readable warning: a missing MTL file, material
//! or texture falls back to a default, degenerate triangles are skipped,
//! albedo above [`ALBEDO_MAX`] is clamped.
//!
//! `tobj` reports no line numbers, so the OBJ is fed to it through a line
//! tap that counts lines, mirrors its material lookups and stops it before
//! input that would make it panic (see the notes on [`load`]). Errors that
//! `tobj` only detects at the end of a face group (an index past the last
//! vertex) and bad coordinates (which it accepts) are located afterwards by
//! a streaming second scan of the file that runs only on that error path.

use crate::error::ImageError;
use rayon::prelude::*;
use serde::Serialize;
use std::cell::RefCell;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::fmt;
use std::fs::File;
use std::io::{self, BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

use crate::error::SceneError;
use crate::math::{cross, norm, sub};

mod build;
pub mod files;
pub mod gltf;
pub mod image_source;
pub use image_source::{DiffuseTexture, ImageSource, Wrap};
mod material;
mod tap;
use build::build_scene;
pub mod triangulate;
use tap::{locate_bad_face, LineTap, TapOutcome};

/// Albedo components are clamped to at most this value: every `ρ < 1` keeps
/// `T_∞ = F (I − diag(ρ) F)^{-1}` finite, and 0.99 bounds the infinite-bounce
/// amplification `1/(1 − ρ)` by 100.
pub const ALBEDO_MAX: f32 = 0.99;

/// Albedo (linear, all three channels) of the default material, used for
/// triangles without a material, for materials that are named but not
/// defined, and for materials that have neither `Kd` nor `map_Kd`.
pub const DEFAULT_ALBEDO: f32 = 0.8;

/// Largest accepted absolute vertex coordinate. The voxel grid works in
/// `f32`, whose 24-bit mantissa spaces representable values 8 units apart
/// at 1e8: beyond it grid coordinates and voxel indices computed from them
/// lose their meaning, and such values in practice come from unit mix-ups
/// or corrupt files rather than real scenes.
pub const MAX_ABS_COORDINATE: f32 = 1e8;

/// A triangle whose area is at most this ratio times the square of its
/// longest edge (computed in `f64`) is degenerate: it is skipped and
/// counted. The ratio is scale-invariant, so tiny but well-shaped triangles
/// survive while slivers with collinear vertices do not.
pub const DEGENERATE_AREA_RATIO: f64 = 1e-12;

/// Name given to the default material (parenthesised so that it is
/// unlikely to collide with a name from an MTL file).
pub const DEFAULT_MATERIAL_NAME: &str = "(default)";

/// A material as the bake sees it.
#[derive(Clone, Debug, Serialize)]
pub struct Material {
    /// The name from `newmtl`, or [`DEFAULT_MATERIAL_NAME`].
    pub name: String,
    /// Linear RGB albedo used by the bake: `Kd` times the linear average of
    /// the `map_Kd` texture, clamped to `ALBEDO_MAX`.
    pub albedo: [f32; 3],
    /// `Ke`, emitted radiant exitance (linear RGB).
    pub emission: [f32; 3],
    /// `Kd` as written in the MTL file. When the file gives no `Kd`, this is
    /// 1 for a textured material (the texture alone) and [`DEFAULT_ALBEDO`]
    /// otherwise.
    pub kd: [f32; 3],
    /// The diffuse texture (an OBJ's `map_Kd`, resolved relative to the MTL
    /// file; a glTF material's `baseColorTexture`), if it loaded.
    pub diffuse_texture: Option<DiffuseTexture>,
    /// Both sides of the surface are seen (a glTF material's
    /// `doubleSided`): the bake gives its triangles back sides
    /// ([`Scene::with_back_sides_of`]). OBJ materials are one-sided.
    pub double_sided: bool,
}

/// Repairs made while loading, each counted.
#[derive(Clone, Debug, Default, Serialize, PartialEq, Eq)]
pub struct Repairs {
    /// Triangles with (near) zero area or repeated vertices, skipped. Faces
    /// with only one or two vertices (which `tobj` ignores) count here too:
    /// they are zero-area triangles.
    pub degenerate_triangles: u64,
    /// Albedo components above `ALBEDO_MAX` (one per channel per material),
    /// clamped to it. A component exactly equal to `ALBEDO_MAX` is left as
    /// it is and not counted.
    pub clamped_albedo_components: u64,
    /// Material names used by `usemtl` but defined by no loaded MTL file
    /// (including names from an MTL file that is missing): default albedo.
    pub missing_materials: u64,
    /// Texture files that could not be read or decoded: `Kd` alone used.
    pub missing_textures: u64,
    /// Triangles whose geometric normal (from the counter-clockwise winding)
    /// points against the mean of the file's three vertex normals. Only
    /// reported: the geometry is kept as the file gives it.
    pub winding_disagrees_with_normals: u64,
    /// Polygon faces (more than three vertices) that are not convex,
    /// triangulated by ear clipping instead of a fan ([`triangulate`]).
    pub nonconvex_polygons: u64,
    /// Of those, polygons ear clipping could not cut (an outline that
    /// crosses itself, or more than
    /// [`triangulate::EAR_CLIPPING_MAX_VERTICES`] vertices): fanned, with a
    /// warning, as they may cover the wrong area.
    pub untriangulated_polygons: u64,
}

/// A loaded, validated triangle scene. All models of the OBJ are merged into
/// one vertex array; vertices not used by any kept triangle are dropped.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The OBJ file the scene was loaded from.
    pub source: PathBuf,
    /// Vertex positions, each used by at least one triangle.
    pub positions: Vec<[f32; 3]>,
    /// Per-vertex normals, empty when the file has none. When only some
    /// vertices have one, the others get the area-weighted mean of their
    /// triangles' geometric normals (and a warning says how many).
    pub normals: Vec<[f32; 3]>,
    /// Per-vertex texture coordinates, empty when the file has none. When
    /// only some vertices have them, the others get `[0, 0]` (and a warning
    /// says how many).
    pub texcoords: Vec<[f32; 2]>,
    /// Counter-clockwise triangles (the OBJ's winding), indices into `positions`.
    pub triangles: Vec<[u32; 3]>,
    /// Material index of each triangle, into `materials`.
    pub triangle_material: Vec<u32>,
    /// The materials used by at least one triangle, in MTL order, followed
    /// by the default material when some triangle needs it.
    pub materials: Vec<Material>,
    /// What the loader repaired, counted.
    pub repairs: Repairs,
    /// Human-readable warnings (missing MTL, missing textures, ...).
    pub warnings: Vec<String>,
    /// Back sides added to some triangles ([`Scene::with_back_sides`],
    /// [`Scene::with_back_sides_of`]): the last `twins.len()` triangles are
    /// the reversed copies of the triangles listed here, in this
    /// (ascending) order. Empty for a scene as loaded.
    pub twins: Vec<u32>,
    /// The camera and lights the scene file gives (glTF); empty for OBJ.
    pub authored: Authored,
}

/// A camera and lights that come with the scene file: a glTF file's first
/// camera and its `KHR_lights_punctual` lights, converted as
/// [`gltf`] documents. A camera-and-lights file still overrides them;
/// where neither is given, [`crate::default_view`] chooses.
#[derive(Clone, Debug, Default)]
pub struct Authored {
    /// The camera of the first camera node met (scene order), if any.
    pub camera: Option<crate::scene_config::Camera>,
    /// Every light node's light, in scene order.
    pub lights: Vec<crate::scene_config::Light>,
}

/// Axis-aligned bounds as they appear in the JSON summary.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Bounds {
    /// Smallest coordinate on each axis.
    pub min: [f32; 3],
    /// Largest coordinate on each axis.
    pub max: [f32; 3],
}

/// What `radiosity info` prints: counts, bounds, areas, repairs, warnings.
/// Serialises to JSON with the keys named by the fields.
#[derive(Clone, Debug, Serialize)]
pub struct SceneSummary {
    /// The OBJ file the scene came from.
    pub source: PathBuf,
    /// Number of triangles.
    pub triangles: usize,
    /// Number of vertices.
    pub vertices: usize,
    /// Number of materials (including the default one when used).
    pub materials: usize,
    /// Number of materials with a nonzero emission.
    pub emissive_materials: usize,
    /// Whether the scene carries vertex normals.
    pub has_normals: bool,
    /// Whether the scene carries texture coordinates.
    pub has_texcoords: bool,
    /// Bounds of the vertices used by triangles.
    pub bounds: Bounds,
    /// Total surface area of the triangles.
    pub area: f64,
    /// Surface area of the triangles with an emissive material.
    pub emissive_area: f64,
    /// The loader's repairs.
    pub repairs: Repairs,
    /// The loader's warnings.
    pub warnings: Vec<String>,
    /// The length unit: "metres" for glTF (fixed by its spec), "scene units"
    /// for OBJ (which has none).
    pub units: String,
    /// Lights and whether a camera come with the file (glTF).
    pub authored_lights: usize,
    pub authored_camera: bool,
}

impl Scene {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Axis-aligned bounds `(min, max)` of the vertices used by triangles;
    /// `([0; 3], [0; 3])` for a scene without triangles.
    pub fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for tri in &self.triangles {
            for &v in tri {
                let p = self.positions[v as usize];
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
        }
        if self.triangles.is_empty() {
            ([0.0; 3], [0.0; 3])
        } else {
            (lo, hi)
        }
    }

    /// The three corners of triangle `t` in `f64`.
    pub fn corners(&self, t: usize) -> [[f64; 3]; 3] {
        self.triangles[t].map(|v| self.positions[v as usize].map(f64::from))
    }

    /// Area of triangle `t`, computed in `f64`.
    pub fn triangle_area(&self, t: usize) -> f64 {
        let [a, b, c] = self.corners(t);
        0.5 * norm(cross(sub(b, a), sub(c, a)))
    }

    /// The scene with a back side for every surface: each triangle `t` of
    /// the `T` is followed, at index `t + T`, by its twin with the opposite
    /// winding on its own copies of the vertices (normals negated, texture
    /// coordinates kept), with the same material. A bake of it gives
    /// patches on both sides of every surface (scenes whose winding cannot
    /// be trusted); the covered-point rule does not let a surface's twin
    /// cover it (a coincident front face cancels a back face,
    /// `radiosity_bake::cover`).
    pub fn with_back_sides(&self) -> Scene {
        let all: Vec<u32> = (0..self.triangles.len() as u32).collect();
        self.with_back_sides_of(&all)
    }

    /// The scene with a reversed copy (a back side, as
    /// [`Scene::with_back_sides`] makes) of each triangle in `twinned`
    /// appended, in that order (`twinned` must be ascending, without
    /// repeats; [`Scene::twins`] records it). The winding check
    /// (`bake::winding`) chooses the list; the bake file records it and the
    /// run time rebuilds the baked scene with this. Twins get vertices of
    /// their own, with reversed normals. Indices out of range are ignored.
    pub fn with_back_sides_of(&self, twinned: &[u32]) -> Scene {
        let mut s = self.clone();
        let twinned: Vec<u32> = twinned
            .iter()
            .copied()
            .filter(|&t| (t as usize) < self.triangles.len())
            .collect();
        if twinned.is_empty() {
            return s;
        }
        // The twins' vertices: every vertex a twinned triangle uses, once,
        // in vertex order (so that with every triangle twinned, vertex `v`'s
        // copy is `v + V`, as files baked two-sided before this function
        // existed index them).
        let mut used = vec![false; self.positions.len()];
        for &t in &twinned {
            for &v in &s.triangles[t as usize] {
                used[v as usize] = true;
            }
        }
        let mut remap: Vec<u32> = vec![u32::MAX; self.positions.len()];
        for v in (0..self.positions.len()).filter(|&v| used[v]) {
            remap[v] = s.positions.len() as u32;
            s.positions.push(self.positions[v]);
            if let Some(n) = self.normals.get(v) {
                s.normals.push([-n[0], -n[1], -n[2]]);
            }
            if let Some(uv) = self.texcoords.get(v) {
                s.texcoords.push(*uv);
            }
        }
        for &t in &twinned {
            let tri = s.triangles[t as usize];
            s.triangles.push([
                remap[tri[0] as usize],
                remap[tri[2] as usize],
                remap[tri[1] as usize],
            ]);
            s.triangle_material.push(self.triangle_material[t as usize]);
        }
        s.twins = twinned;
        s
    }

    /// The coincident reversed copy of triangle `t` (its twin, for a twin
    /// the triangle it copies), if it has one ([`Scene::twins`]).
    pub fn twin(&self, t: usize) -> Option<usize> {
        let first = self.triangles.len() - self.twins.len();
        if t >= first {
            return self.twins.get(t - first).map(|&o| o as usize);
        }
        self.twins
            .binary_search(&(t as u32))
            .ok()
            .map(|k| first + k)
    }

    /// Triangles that are not twins: the scene's own, drawn by a renderer.
    pub fn own_triangles(&self) -> usize {
        self.triangles.len() - self.twins.len()
    }

    /// Every triangle's unit normal ([`Scene::triangle_normal`]), in triangle
    /// order.
    pub fn triangle_normals(&self) -> Vec<[f64; 3]> {
        (0..self.triangles.len())
            .map(|t| self.triangle_normal(t))
            .collect()
    }

    /// Unit geometric normal of triangle `t` from its counter-clockwise
    /// winding, in `f64`; the zero vector for a zero-area triangle (which a
    /// loaded scene does not contain).
    pub fn triangle_normal(&self, t: usize) -> [f64; 3] {
        let [a, b, c] = self.corners(t);
        let n = cross(sub(b, a), sub(c, a));
        let len = norm(n);
        if len > 0.0 {
            n.map(|x| x / len)
        } else {
            [0.0; 3]
        }
    }

    /// Total area of all triangles.
    pub fn surface_area(&self) -> f64 {
        // Folding from +0.0: `Sum` for floats starts at -0.0, which would
        // print as "-0" for a scene without emitters.
        (0..self.triangles.len())
            .map(|t| self.triangle_area(t))
            .fold(0.0, |a, b| a + b)
    }

    /// Total area of the triangles whose material has a nonzero emission.
    pub fn emissive_area(&self) -> f64 {
        (0..self.triangles.len())
            .filter(|&t| is_emissive(&self.materials[self.triangle_material[t] as usize]))
            .map(|t| self.triangle_area(t))
            .fold(0.0, |a, b| a + b)
    }

    /// Counts, bounds, areas, repairs and warnings for `radiosity info` and
    /// the bake report.
    pub fn summary(&self) -> SceneSummary {
        let (min, max) = self.bounds();
        SceneSummary {
            source: self.source.clone(),
            triangles: self.triangles.len(),
            vertices: self.positions.len(),
            materials: self.materials.len(),
            emissive_materials: self.materials.iter().filter(|m| is_emissive(m)).count(),
            has_normals: !self.normals.is_empty(),
            has_texcoords: !self.texcoords.is_empty(),
            bounds: Bounds { min, max },
            area: self.surface_area(),
            emissive_area: self.emissive_area(),
            repairs: self.repairs.clone(),
            warnings: self.warnings.clone(),
            units: if gltf::is_gltf(&self.source) {
                "metres"
            } else {
                "scene units"
            }
            .to_owned(),
            authored_lights: self.authored.lights.len(),
            authored_camera: self.authored.camera.is_some(),
        }
    }
}

/// Whether a material emits light (any channel of `Ke` above zero).
fn is_emissive(m: &Material) -> bool {
    m.emission.iter().any(|&e| e > 0.0)
}

impl fmt::Display for SceneSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let r = &self.repairs;
        let [x0, y0, z0] = self.bounds.min;
        let [x1, y1, z1] = self.bounds.max;
        writeln!(f, "scene       {}", self.source.display())?;
        writeln!(f, "triangles   {}", self.triangles)?;
        writeln!(
            f,
            "vertices    {} (normals: {}, texcoords: {})",
            self.vertices,
            if self.has_normals { "yes" } else { "no" },
            if self.has_texcoords { "yes" } else { "no" }
        )?;
        writeln!(
            f,
            "materials   {} ({} emissive)",
            self.materials, self.emissive_materials
        )?;
        writeln!(
            f,
            "bounds      [{x0:.4}, {y0:.4}, {z0:.4}] .. [{x1:.4}, {y1:.4}, {z1:.4}] ({})",
            self.units
        )?;
        if self.authored_camera || self.authored_lights > 0 {
            writeln!(
                f,
                "view        {} camera, {} light(s) from the file",
                if self.authored_camera { "a" } else { "no" },
                self.authored_lights
            )?;
        }
        writeln!(f, "area        {:.6}", self.area)?;
        writeln!(f, "emissive    {:.6}", self.emissive_area)?;
        writeln!(
            f,
            "repairs     {} degenerate triangles skipped, {} albedo components clamped, \
             {} missing materials, {} missing textures, {} triangles wound against their normals, \
             {} non-convex polygons cut by ear clipping",
            r.degenerate_triangles,
            r.clamped_albedo_components,
            r.missing_materials,
            r.missing_textures,
            r.winding_disagrees_with_normals,
            r.nonconvex_polygons
        )?;
        if self.warnings.is_empty() {
            writeln!(f, "warnings    none")?;
        } else {
            writeln!(f, "warnings    {}", self.warnings.len())?;
            for w in &self.warnings {
                writeln!(f, "  - {w}")?;
            }
        }
        Ok(())
    }
}

/// The exact piecewise sRGB electro-optical transfer function: an encoded
/// value in `[0, 1]` to linear light.
pub fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

// ---------------------------------------------------------------------------
// Loading
// ---------------------------------------------------------------------------

/// The `tobj` options the loader uses: triangles only, one index per vertex.
// The struct update is needed when another crate in the build enables
// tobj's `merging` or `reordering` features, which add fields.
#[allow(clippy::needless_update)]
fn load_options() -> tobj::LoadOptions {
    tobj::LoadOptions {
        // Polygons are triangulated by the loader (`triangulate`): tobj's
        // fan is wrong for non-convex ones.
        triangulate: false,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    }
}

/// Loads a scene, validates it and repairs what can be repaired: a glTF
/// file (`.gltf`, `.glb`: [`gltf::load`]) or an OBJ with its MTL files and
/// textures (any other name; see the module documentation).
///
/// Errors: [`SceneError::Io`] when the OBJ cannot be read;
/// [`SceneError::Parse`] naming the file (OBJ or MTL) and the 1-based line
/// for malformed records, non-finite or huge coordinates, face indices out
/// of range, and negative or non-finite `Kd`/`Ke`; [`SceneError::Empty`]
/// when no triangle remains; [`SceneError::Invalid`] for the rest (more
/// than `u32::MAX` vertices, or a `tobj` failure that could not be tied to
/// a line).
///
/// Vertices that no face uses are dropped by tobj and not validated. When a
/// used vertex is bad, the error points at the first bad `v` line of the
/// file. A missing MTL file is a warning; the names `usemtl` then looks up
/// in vain are counted in [`Repairs::missing_materials`].
///
/// Notes on `tobj` 4.0.5 that shape this function:
/// - `Ke` is parsed into `Material::emissive`, not `unknown_param`.
/// - `Ka`/`Kd`/`Ks`/`Ke` with fewer than three numbers panic inside tobj;
///   the MTL reader here expands the single-value form the MTL spec allows
///   (`Kd 0.5` means grey) and rejects two values with a line number.
/// - Relative (negative) face indices that reach before the first
///   texcoord/normal, and indices near `isize::MAX`, overflow arithmetic in
///   tobj (a panic with overflow checks on); such faces are rejected before
///   tobj sees them.
/// - Absolute face indices are only checked when a face group ends (at the
///   next `o`/`g`/`usemtl` or at the end of the file), so tobj accepts
///   forward references within a group and reports an index past the end
///   late; the second scan finds the face line.
/// - A mesh where only some faces carry `/vt` or `//vn` indices gets
///   texcoord/normal arrays shorter than its positions (and misaligned);
///   such arrays are discarded for that mesh and the values filled in.
/// - Non-UTF-8 lines make tobj fail with a bare "read error"; the line tap
///   decodes them lossily instead and warns.
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    if gltf::is_gltf(path) {
        return gltf::load(path);
    }
    load_obj(path)
}

/// [`load`] for an OBJ file.
fn load_obj(path: &Path) -> Result<Scene, SceneError> {
    let file = File::open(path).map_err(|source| SceneError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let obj_dir = path.parent().unwrap_or_else(|| Path::new("")).to_path_buf();
    let state = RefCell::new(ObjState::default());

    let mut tap = LineTap::new(BufReader::with_capacity(1 << 16, file), |line, buf| {
        obj_line_hook(&state, line, buf)
    });
    let result = tobj::load_obj_buf(&mut tap, &load_options(), |relative: &Path| {
        load_material_library(&state, &obj_dir.join(relative))
    });
    let tap = tap.finish();
    let mut st = state.into_inner();

    if let Some(err) = st.fatal.take() {
        return Err(err);
    }
    let models = match result {
        Ok((models, _)) => models,
        Err(err) => return Err(obj_error(path, err, tap)),
    };
    if tap.lossy_lines > 0 {
        st.warnings.push(format!(
            "{}: {} line(s) were not valid UTF-8 and were decoded lossily (first: line {})",
            path.display(),
            tap.lossy_lines,
            tap.first_lossy_line
        ));
    }
    let rounding = (st.rounding, st.rounding_line);
    let mut scene = build_scene(path, models, st)?;
    if let Some(w) = precision_warning(path, rounding, &scene) {
        scene.warnings.push(w);
    }
    Ok(scene)
}

/// Vertex coordinates change by more than this fraction of the scene's
/// extent when stored as `f32` (every stage keeps positions in `f32`):
/// 0.4 mm in a 4 m room. Coordinates far from the origin relative to the
/// model's size do this (a building placed at its survey coordinates,
/// 5.4e6 m north: `f32` spacing 0.5 m there).
pub const PRECISION_WARNING: f64 = 1e-4;

/// The warning for a file whose coordinates lose more than
/// [`PRECISION_WARNING`] of the loaded scene's extent as `f32` (`rounding`:
/// the largest change and its first line), naming them and the remedy.
fn precision_warning(path: &Path, (rounding, line): (f64, usize), scene: &Scene) -> Option<String> {
    let (lo, hi) = scene.bounds();
    let extent = (0..3).map(|a| f64::from(hi[a] - lo[a])).fold(0.0, f64::max);
    if rounding <= PRECISION_WARNING * extent {
        return None;
    }
    let far = (0..3)
        .map(|a| f64::from(lo[a].abs().max(hi[a].abs())))
        .fold(0.0, f64::max);
    Some(format!(
        "{}: coordinates up to {far:.6e} change by up to {rounding:.3e} when stored as 32-bit floats ({:.3} % of the scene's extent {extent:.4e}; first at line {line}): the geometry is distorted. Move the model near the origin (its bounds' centre at 0) before exporting",
        path.display(),
        100.0 * rounding / extent,
    ))
}

/// Turns a `tobj` failure on the OBJ into an error naming the file and line.
fn obj_error(path: &Path, err: tobj::LoadError, tap: TapOutcome) -> SceneError {
    if let Some((line, message)) = tap.halted {
        return SceneError::Parse {
            path: path.to_path_buf(),
            line,
            message,
        };
    }
    if let Some(source) = tap.io_error {
        return SceneError::Io {
            path: path.to_path_buf(),
            source,
        };
    }
    use tobj::LoadError as E;
    match err {
        // These are found when a face group is exported, after its lines
        // were read: the tap's line is not the culprit, so scan for it.
        E::FaceVertexOutOfBounds
        | E::FaceTexCoordOutOfBounds
        | E::FaceNormalOutOfBounds
        | E::FaceColorOutOfBounds
        | E::InvalidPolygon => locate_bad_face(path).unwrap_or_else(|| SceneError::Parse {
            path: path.to_path_buf(),
            line: tap.line,
            message: format!(
                "{err} in the face group ending at this line (the face could not be \
                 located): `{}`",
                clip(&tap.last_line)
            ),
        }),
        _ => SceneError::Parse {
            path: path.to_path_buf(),
            line: tap.line,
            message: format!("{err}: `{}`", clip(&tap.last_line)),
        },
    }
}

/// State shared between the OBJ line hook and the material-library loader
/// while `tobj` runs (they are called alternately, never nested).
#[derive(Default)]
struct ObjState {
    /// Names defined by the material libraries loaded so far; mirrors the
    /// lookup table tobj consults at each `usemtl`.
    defined: HashSet<String>,
    /// Every material tobj holds, in its order, with the MTL file it came from.
    materials: Vec<(tobj::Material, PathBuf)>,
    /// `usemtl` names that were not defined when used, with the first line.
    missing_names: BTreeMap<String, usize>,
    /// Numbers of `v`, `vt` and `vn` records read so far.
    counts: [usize; 3],
    /// `f` records with one or two vertices, which tobj ignores.
    short_faces: u64,
    /// Number of `f` records.
    faces: u64,
    warnings: Vec<String>,
    /// An error found in a material library; it stops the load.
    fatal: Option<SceneError>,
    /// The largest change of a vertex coordinate from storing it as `f32`
    /// (read in f64 from the file), and its first line.
    rounding: f64,
    rounding_line: usize,
}

/// Inspects one OBJ line before tobj parses it: counts records, mirrors
/// material lookups and rejects face indices that would make tobj panic.
fn obj_line_hook(state: &RefCell<ObjState>, line_no: usize, buf: &[u8]) -> Result<(), String> {
    let mut st = state.borrow_mut();
    if st.fatal.is_some() {
        return Err("stopped after an error in a material library".to_owned());
    }
    // The tap guarantees UTF-8; a failure here would be a bug, so treat the
    // line as blank rather than panic.
    let text = std::str::from_utf8(buf).unwrap_or("");
    let line = strip_newline(text);
    let mut words = line.split_whitespace();
    match words.next() {
        Some("v") => {
            st.counts[0] += 1;
            // The coordinates in f64 (tobj keeps f32): how much storing
            // them changes them ([`precision_warning`]).
            for x in words.take(3).filter_map(|w| w.parse::<f64>().ok()) {
                let r = (x - f64::from(x as f32)).abs();
                if r > st.rounding {
                    st.rounding = r;
                    st.rounding_line = line_no;
                }
            }
        }
        Some("vt") => st.counts[1] += 1,
        Some("vn") => st.counts[2] += 1,
        Some("f") => {
            st.faces += 1;
            let mut vertices = 0;
            for token in words {
                vertices += 1;
                for (kind, part) in token.split('/').take(3).enumerate() {
                    check_index_early(part, kind, st.counts[kind])
                        .map_err(|m| format!("{m}: `{}`", clip(line)))?;
                }
            }
            if (1..3).contains(&vertices) {
                st.short_faces += 1;
            }
        }
        Some("usemtl") => {
            // The same expression tobj uses to take the name.
            let name = line.split_once(' ').unwrap_or_default().1.trim();
            if !name.is_empty() && !st.defined.contains(name) {
                st.missing_names.entry(name.to_owned()).or_insert(line_no);
            }
        }
        _ => {}
    }
    Ok(())
}

/// What each slot of a face vertex `v/vt/vn` refers to, for messages.
const INDEX_KINDS: [&str; 3] = ["vertex", "texture coordinate", "normal"];

/// Rejects, before tobj sees them, face indices that are certainly invalid
/// and that tobj mishandles: zero, relative indices reaching before the
/// first record, and absurdly large values (which overflow its arithmetic).
/// Indices past the current count are left to tobj, which allows forward
/// references within a face group.
fn check_index_early(part: &str, kind: usize, count: usize) -> Result<(), String> {
    if part.is_empty() {
        return Ok(());
    }
    // A value tobj cannot parse makes it fail at this very line, with the
    // right line number; leave that to it.
    let Ok(x) = part.parse::<isize>() else {
        return Ok(());
    };
    let what = INDEX_KINDS[kind];
    if x == 0 {
        return Err(format!(
            "{what} index 0 is invalid (OBJ indices start at 1)"
        ));
    }
    if x < 0 && x.unsigned_abs() > count {
        return Err(format!(
            "relative {what} index {x} reaches before the first {what} (only {count} defined so far)"
        ));
    }
    // No file holds 10^15 records; beyond that tobj's index arithmetic overflows.
    if x > 1_000_000_000_000_000 {
        return Err(format!("{what} index {x} is out of range"));
    }
    Ok(())
}

/// Loads one MTL file for tobj and records the outcome in `state`: a
/// missing file is a warning (its materials get the default albedo), a
/// malformed one stops the load with an error naming the file and line.
fn load_material_library(state: &RefCell<ObjState>, path: &Path) -> tobj::MTLLoadResult {
    // A directory opens but cannot be read; `mtllib` without a name gives one.
    let opened = if path.is_dir() {
        Err(io::Error::other("it is a directory"))
    } else {
        File::open(path)
    };
    let file = match opened {
        Ok(f) => f,
        Err(e) => {
            state.borrow_mut().warnings.push(format!(
                "material library {} could not be opened ({e}); its materials get the \
                 default albedo {DEFAULT_ALBEDO}",
                path.display()
            ));
            return Err(tobj::LoadError::OpenFileFailed);
        }
    };
    let mut current = String::new();
    let mut tap = LineTap::new(BufReader::new(file), |_, buf| {
        mtl_line_hook(&mut current, buf)
    });
    let result = tobj::load_mtl_buf(&mut tap);
    let tap = tap.finish();
    let mut st = state.borrow_mut();
    match result {
        Ok((materials, map)) => {
            if tap.lossy_lines > 0 {
                st.warnings.push(format!(
                    "{}: {} line(s) were not valid UTF-8 and were decoded lossily (first: line {})",
                    path.display(),
                    tap.lossy_lines,
                    tap.first_lossy_line
                ));
            }
            for m in &materials {
                st.defined.insert(m.name.clone());
                st.materials.push((m.clone(), path.to_path_buf()));
            }
            Ok((materials, map))
        }
        Err(err) => {
            let error = if let Some((line, message)) = tap.halted {
                SceneError::Parse {
                    path: path.to_path_buf(),
                    line,
                    message,
                }
            } else if let Some(source) = tap.io_error {
                SceneError::Io {
                    path: path.to_path_buf(),
                    source,
                }
            } else {
                SceneError::Parse {
                    path: path.to_path_buf(),
                    line: tap.line,
                    message: format!("{err}: `{}`", clip(&tap.last_line)),
                }
            };
            st.fatal.get_or_insert(error);
            Err(err)
        }
    }
}

/// Inspects one MTL line before tobj parses it. Colour records get their
/// numbers checked (tobj panics on fewer than three), the one-number form
/// is expanded to three, and `Kd`/`Ke` must be finite and non-negative.
/// `current` tracks the material being defined, for messages.
fn mtl_line_hook(current: &mut String, buf: &mut Vec<u8>) -> Result<(), String> {
    let text = std::str::from_utf8(buf).unwrap_or("");
    let line = strip_newline(text).trim();
    let mut words = line.split_whitespace();
    let key = match words.next() {
        Some("newmtl") => {
            // The same expression tobj uses to take the name.
            *current = line[6..].trim().to_owned();
            return Ok(());
        }
        Some("Ka") => "Ka",
        Some("Kd") => "Kd",
        Some("Ks") => "Ks",
        Some("Ke") => "Ke",
        _ => return Ok(()),
    };
    let material = if current.is_empty() {
        "(before any newmtl)".to_owned()
    } else {
        format!("`{current}`")
    };
    let tokens: Vec<&str> = words.collect();
    if tokens.is_empty() || tokens.len() == 2 {
        return Err(format!(
            "material {material}: `{key}` needs 1 or 3 numbers, found {}: `{}`",
            tokens.len(),
            clip(line)
        ));
    }
    let mut values = [0.0f32; 3];
    for (k, token) in tokens.iter().take(3).enumerate() {
        values[k] = token.parse().map_err(|_| {
            format!(
                "material {material}: `{key}` value `{token}` is not a number: `{}`",
                clip(line)
            )
        })?;
    }
    if tokens.len() == 1 {
        values = [values[0]; 3];
        let expanded = format!("{key} {0} {0} {0}\n", tokens[0]).into_bytes();
        *buf = expanded;
    }
    if (key == "Kd" || key == "Ke") && values.iter().any(|v| !v.is_finite() || *v < 0.0) {
        return Err(format!(
            "material {material}: {key} {:?} has a negative or non-finite component",
            values
        ));
    }
    Ok(())
}

/// Strips the line ending the way `BufRead::lines` does.
fn strip_newline(text: &str) -> &str {
    let text = text.strip_suffix('\n').unwrap_or(text);
    text.strip_suffix('\r').unwrap_or(text)
}

/// Shortens a line for an error message.
fn clip(line: &str) -> String {
    const MAX: usize = 120;
    let line = strip_newline(line).trim();
    if line.chars().count() <= MAX {
        line.to_owned()
    } else {
        let head: String = line.chars().take(MAX).collect();
        format!("{head}...")
    }
}

// ---------------------------------------------------------------------------
// Building the scene
// ---------------------------------------------------------------------------

#[cfg(test)]
mod tests {
    use super::material::texture_file_name;
    use super::*;

    #[test]
    fn srgb_eotf_matches_the_standard_at_key_points() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-15);
        assert!((srgb_to_linear(0.04045) - 0.04045 / 12.92).abs() < 1e-15);
        // 0.5 encoded is about 0.214 linear.
        assert!((srgb_to_linear(0.5) - 0.214_041_140_482_232_5).abs() < 1e-12);
    }

    #[test]
    fn texture_names_drop_options_and_windows_separators() {
        assert_eq!(texture_file_name("wall.png"), "wall.png");
        assert_eq!(texture_file_name("  my wall.png "), "my wall.png");
        assert_eq!(
            texture_file_name("-bm 0.5 -s 1 1 1 tex\\wall.png"),
            "tex/wall.png"
        );
    }

    #[test]
    fn early_index_check_rejects_only_certain_errors() {
        assert!(
            check_index_early("3", 0, 2).is_ok(),
            "forward references are tobj's call"
        );
        assert!(check_index_early("-2", 0, 2).is_ok());
        assert!(check_index_early("-3", 1, 2).is_err());
        assert!(check_index_early("0", 2, 2).is_err());
        assert!(check_index_early("9223372036854775807", 1, 2).is_err());
        assert!(
            check_index_early("abc", 0, 2).is_ok(),
            "tobj reports its own parse errors"
        );
    }

    #[test]
    fn mtl_hook_expands_single_values_and_rejects_bad_ones() {
        let mut current = String::from("m");
        let mut buf = b"Kd 0.5\n".to_vec();
        mtl_line_hook(&mut current, &mut buf).unwrap();
        assert_eq!(buf, b"Kd 0.5 0.5 0.5\n");
        let mut buf = b"Kd 0.5 0.5\n".to_vec();
        assert!(mtl_line_hook(&mut current, &mut buf).is_err());
        let mut buf = b"Ke -1 0 0\n".to_vec();
        assert!(mtl_line_hook(&mut current, &mut buf)
            .unwrap_err()
            .contains("`m`"));
        let mut buf = b"Ks -1 0 0\n".to_vec();
        assert!(
            mtl_line_hook(&mut current, &mut buf).is_ok(),
            "Ks is not used"
        );
    }

    #[test]
    fn line_tap_counts_lines_and_repairs_utf8() {
        let data: &[u8] = b"a\nb\xff\nc";
        let mut seen = Vec::new();
        let mut tap = LineTap::new(data, |n, buf: &mut Vec<u8>| {
            seen.push((n, String::from_utf8(buf.clone()).unwrap()));
            Ok(())
        });
        let lines: Vec<String> = (&mut tap).lines().map(|l| l.unwrap()).collect();
        assert_eq!(lines, ["a", "b\u{fffd}", "c"]);
        let outcome = tap.finish();
        assert_eq!(outcome.line, 3);
        assert_eq!(outcome.lossy_lines, 1);
        assert_eq!(outcome.first_lossy_line, 2);
        assert_eq!(seen.len(), 3);
    }
}
