//! The sky on the patches: `D_sky = Σ_c L̄_c T_c` per patch and channel,
//! from the sky's mean radiance per sky cell ([`Sky::cell_radiance`]) and
//! each patch's baked visibility per cell ([`radiosity_bakefile::sky`]). It enters `B0`
//! as `ρ ∘ D_sky` like any light's irradiance and is bounced by the same
//! gather ([`crate::Runtime::set_sky`]).

use radiosity_bakefile::baked::Baked;
use radiosity_core::sky::Sky;

/// Why a sky cannot light a bake's frames.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SkyError {
    /// The bake has no sky visibility.
    #[error(
        "the bake {file} has no sky visibility (made before skies or with an older layout of \
         it, or with form factors that cast no rays): a sky lights nothing until the scene is \
         baked again"
    )]
    NoVisibility { file: String },
    /// A value of the sky is out of its range ([`Sky::validate`]).
    #[error("{0}")]
    Invalid(radiosity_core::error::InvalidField),
    /// An environment map whose file has not been read
    /// ([`Sky::load_map`]; the camera-and-lights file reads it).
    #[error("the sky's environment map {file} has not been read (Sky::load_map)")]
    NotRead { file: String },
}

/// Checks that `sky` can light `baked`'s frames (module doc).
pub fn check(baked: &Baked, sky: &Sky) -> Result<(), SkyError> {
    if baked.sky.is_empty() {
        return Err(SkyError::NoVisibility {
            file: baked.file.clone(),
        });
    }
    if let Sky::Envmap {
        file, map: None, ..
    } = sky
    {
        return Err(SkyError::NotRead {
            file: file.display().to_string(),
        });
    }
    sky.validate().map_err(SkyError::Invalid)
}

/// `D_sky` per channel and patch (matrix order) under `sky`.
pub fn irradiance(baked: &Baked, sky: &Sky) -> Result<[Vec<f32>; 3], SkyError> {
    check(baked, sky)?;
    let l = sky.cell_radiance();
    let v = &baked.sky;
    let e: Vec<[f64; 3]> = (0..baked.patches.len())
        .map(|i| radiosity_core::sky::cells::irradiance(&l, v.patch(i)))
        .collect();
    Ok(std::array::from_fn(|c| {
        e.iter().map(|v| v[c] as f32).collect()
    }))
}
