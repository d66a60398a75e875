//! The sky on the patches: `D_sky = Σ_c L̄_c T_c` per patch and channel,
//! from the sky's mean radiance per sky cell ([`Sky::cell_radiance`]) and
//! each patch's baked visibility per cell ([`radiosity_bakefile::sky`]). It enters `B0`
//! as `ρ ∘ D_sky` like any light's irradiance and is bounced by the same
//! gather ([`crate::Runtime::set_sky`]).

use radiosity_bakefile::baked::Baked;
use radiosity_core::sky::Sky;

/// A sky asked of a bake that has no sky visibility.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "the bake {file} has no sky visibility (made before skies or with an older layout of it, or \
     with form factors that cast no rays): a sky lights nothing until the scene is baked again"
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
    let l = sky.cell_radiance();
    let v = &baked.sky;
    let e: Vec<[f64; 3]> = (0..baked.patches.len())
        .map(|i| radiosity_core::sky::cells::irradiance(&l, v.patch(i)))
        .collect();
    Ok(std::array::from_fn(|c| {
        e.iter().map(|v| v[c] as f32).collect()
    }))
}
