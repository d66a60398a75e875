//! The sky on the patches: `D_sky = Σ_lm L_lm T_lm` per patch and channel,
//! from the sky's band-2 coefficients ([`Sky::coefficients`]) and each
//! patch's baked transfer ([`radiosity_bakefile::sky`]). It enters `B0`
//! as `ρ ∘ D_sky` like any light's irradiance and is bounced by the same
//! gather ([`crate::Runtime::set_sky`]).

use radiosity_bakefile::baked::Baked;
use radiosity_core::sh;
use radiosity_core::sky::Sky;

/// A sky asked of a bake that has no sky visibility.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "the bake {file} has no sky visibility (made before skies, or with form factors that cast no \
     rays): a sky lights nothing until the scene is baked again"
)]
pub struct NoSkyVisibility {
    pub file: String,
}

/// `D_sky` per channel and patch (matrix order) under `sky`.
pub fn irradiance(baked: &Baked, sky: &Sky) -> Result<[Vec<f32>; 3], NoSkyVisibility> {
    if baked.sky.is_empty() {
        return Err(NoSkyVisibility {
            file: baked.file.clone(),
        });
    }
    let l = sky.coefficients();
    let e: Vec<[f64; 3]> = baked
        .sky
        .transfer
        .iter()
        .map(|t| sh::irradiance(&l, t))
        .collect();
    // A transfer's band-1 and band-2 terms can outweigh band 0 for a
    // patch that sees a sliver of sky under a sky far brighter on the
    // other side: irradiance is never negative, so clamp at 0.
    Ok(std::array::from_fn(|c| {
        e.iter().map(|v| v[c].max(0.0) as f32).collect()
    }))
}
