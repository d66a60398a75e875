//! The bake's inspection files (`--export`): `patches.csv` and
//! `patches.png` (the kept patches, in matrix order), `F.npy`, `T.npy`,
//! `T_decoded.npy` and `albedo.npy`.

use super::form_factor::{self, FormFactors};
use super::pieces::PieceGeo;
use super::preview;
use super::transfer::Transfer;
use super::voxelize::Voxelization;
use crate::error::BakeError;
use radiosity_bakefile::codec::Encoded;
use radiosity_core::npy;
use radiosity_core::patch::Patch;
use radiosity_core::permutation::Permutation;
use radiosity_core::scene::Scene;
use std::io::Write;
use std::path::Path;

/// The files [`export`] writes into its folder (`T_decoded.npy` is written
/// by the bake beside them).
pub const FILES: [&str; 6] = [
    "patches.csv",
    "patches.png",
    "F.npy",
    "T.npy",
    "T_decoded.npy",
    "albedo.npy",
];

/// Writes the inspection files: `patches.csv` (the kept patches, in matrix
/// order), `patches.png` (the pieces, each with the index in `patches` of its
/// patch, drawn by [`preview::render_pieces`]), `F.npy` (n × n), `T.npy` (3 × n × n,
/// channel-major) and `albedo.npy` (n × 3). Refuses, before writing
/// anything, when `T.npy` would exceed [`form_factor::NPY_MAX_BYTES`].
#[allow(clippy::too_many_arguments)]
pub fn export(
    dir: &Path,
    scene_path: &Path,
    bounds: ([f32; 3], [f32; 3]),
    patches: &[Patch],
    pieces: (&[PieceGeo], &[Option<u32>]),
    ff: &FormFactors,
    tr: &Transfer,
    albedo: &[[f32; 3]],
) -> Result<(), BakeError> {
    let n = ff.n;
    let t_bytes = 3 * (n as u64).pow(2) * 4;
    if t_bytes > form_factor::NPY_MAX_BYTES {
        return Err(BakeError::TooLarge {
            stage: "export",
            detail: format!(
                "refusing to export T.npy: 3 × {n} × {n} float32 takes {t_bytes} bytes, above \
                 the {} byte export limit; use fewer patches or no export",
                form_factor::NPY_MAX_BYTES
            ),
        });
    }
    export_patches(dir, patches)?;
    let camera = scene_camera(scene_path, bounds)?;
    let png = dir.join("patches.png");
    preview::render_pieces(pieces.0, pieces.1, patches, &camera, 800, 600)
        .save(&png)
        .map_err(|e| BakeError::Export {
            path: png.clone(),
            detail: e.to_string(),
        })?;
    form_factor::write_f_npy(&dir.join("F.npy"), ff)?;
    let mut t = Vec::with_capacity(3 * n * n);
    for c in 0..3 {
        t.extend_from_slice(tr.channel(c));
    }
    let path = dir.join("T.npy");
    npy::write_f32(&path, &[3, n, n], &t).map_err(|e| export_error(&path, e))?;
    let flat: Vec<f32> = albedo.iter().flatten().copied().collect();
    let path = dir.join("albedo.npy");
    npy::write_f32(&path, &[n, 3], &flat).map_err(|e| export_error(&path, e))?;
    Ok(())
}

/// The camera of the scene's camera/lights file (`NAME.json` beside
/// `NAME.obj`) if there is one, else a default view of the bounds. A file
/// that exists but is invalid is an error.
pub fn scene_camera(
    scene: &Path,
    bounds: ([f32; 3], [f32; 3]),
) -> Result<radiosity_core::scene_config::Camera, BakeError> {
    let json = scene.with_extension("json");
    if json.exists() {
        Ok(radiosity_core::scene_config::load(&json)?.camera)
    } else {
        Ok(preview::default_camera(bounds))
    }
}

/// The header of `patches.csv` (one row per patch, in matrix order).
pub const PATCHES_CSV_HEADER: &str =
    "index,cx,cy,cz,nx,ny,nz,area,albedo_r,albedo_g,albedo_b,emission_r,emission_g,emission_b";

/// Writes `dir/patches.csv`.
pub fn export_patches(dir: &Path, patches: &[Patch]) -> Result<(), BakeError> {
    std::fs::create_dir_all(dir).map_err(|source| BakeError::Io {
        what: "create the export directory",
        path: dir.to_path_buf(),
        source,
    })?;
    let path = dir.join("patches.csv");
    let file = std::fs::File::create(&path).map_err(|e| export_error(&path, e))?;
    let mut w = std::io::BufWriter::new(file);
    let io = |e| export_error(&path, e);
    writeln!(w, "{PATCHES_CSV_HEADER}").map_err(io)?;
    for (i, p) in patches.iter().enumerate() {
        let [cx, cy, cz] = p.centre;
        let [nx, ny, nz] = p.normal;
        let [ar, ag, ab] = p.albedo;
        let [er, eg, eb] = p.emission;
        writeln!(
            w,
            "{i},{cx},{cy},{cz},{nx},{ny},{nz},{},{ar},{ag},{ab},{er},{eg},{eb}",
            p.area
        )
        .map_err(io)?;
    }
    w.flush().map_err(io)?;
    Ok(())
}

/// An inspection file that could not be written.
fn export_error(path: &Path, e: impl std::fmt::Display) -> BakeError {
    BakeError::Export {
        path: path.to_path_buf(),
        detail: e.to_string(),
    }
}

/// What [`export_bake`] writes out: a finished bake's parts.
pub struct Bake<'a> {
    pub scene_path: &'a Path,
    pub scene: &'a Scene,
    pub vox: &'a Voxelization,
    /// Per voxel patch, its index in matrix order (`None`: dropped).
    pub patch_index_of: &'a [Option<u32>],
    pub patches: &'a [Patch],
    pub form_factors: &'a FormFactors,
    pub transfer: &'a Transfer,
    pub albedo: &'a [[f32; 3]],
    pub encoded: &'a Encoded,
    pub permutation: &'a Permutation,
}

/// The bake's inspection files in `dir` ([`export`]'s, the pieces with
/// their owners), and the matrix as the run time decodes it, in the order
/// of `patches.csv` (`T_decoded.npy`).
pub fn export_bake(dir: &Path, b: Bake) -> Result<(), BakeError> {
    let n = b.form_factors.n;
    let geo = crate::pieces::geometry(b.scene, b.vox);
    let owner: Vec<Option<u32>> = b
        .vox
        .pieces
        .iter()
        .map(|p| p.patch.and_then(|v| b.patch_index_of[v as usize]))
        .collect();
    export(
        dir,
        b.scene_path,
        b.scene.bounds(),
        b.patches,
        (&geo, &owner),
        b.form_factors,
        b.transfer,
        b.albedo,
    )?;
    let inverse = Permutation::from_order(b.permutation.inverse.clone())?;
    let decoded = b.encoded.decode();
    let mut flat = Vec::with_capacity(3 * n * n);
    for c in &decoded {
        flat.extend_from_slice(&inverse.apply_symmetric(c, n));
    }
    let path = dir.join("T_decoded.npy");
    npy::write_f32(&path, &[3, n, n], &flat).map_err(|e| BakeError::Export {
        path: path.clone(),
        detail: e.to_string(),
    })
}
