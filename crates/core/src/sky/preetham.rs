//! The clear sky and its sun of Preetham, Shirley and Smits, "A Practical
//! Analytic Model for Daylight" (SIGGRAPH 1999): the sky's luminance and
//! chromaticity by the Perez formula with the paper's turbidity fits
//! (their Appendix A.2), converted CIE xyY → XYZ → linear sRGB; the sun's
//! irradiance after the atmosphere's Rayleigh and aerosol extinction along
//! the relative air mass (their Appendix A.1's optical depths, Kasten's air
//! mass), at three wavelengths standing for the sRGB primaries.
//!
//! Preetham rather than Hosek–Wilkie: a closed form of a few dozen
//! constants instead of a 60 kB table per channel, smooth in the sun's
//! position (the viewer moves the sun every frame), and what this project
//! compares against is its own transport under the same sky (the Mitsuba
//! export writes this sky as an `envmap`, `src/mitsuba/export.rs`), not one
//! sky model against another. Its known limits: too bright near the
//! horizon at low sun and valid for turbidity 2–10 (checked,
//! [`TURBIDITY`]).
//!
//! Units: the paper's luminance in kcd/m² becomes W/(m² sr) of the
//! scene's radiance by 683 lm/W (the photometric convention of the glTF
//! lights, `crates/core/src/scene/gltf/view.rs`), so that a sky's
//! luminance `Y` and a white radiance `[Y/683; 3]` agree.

use std::f64::consts::PI;

/// The turbidity range of the fits (Preetham et al., Section 3).
pub const TURBIDITY: std::ops::RangeInclusive<f32> = 2.0..=10.0;

/// Lumens per watt of the photometric convention.
const LM_PER_W: f64 = 683.0;

/// The solar illuminance outside the atmosphere, lx (the "solar
/// illuminance constant", 128 klx; CIE and IES handbooks).
const SUN_ILLUMINANCE_TOP: f64 = 128_000.0;

/// The sun's elevation below the horizon, in degrees, over which the sky
/// fades to black (civil twilight): the model is undefined below the
/// horizon, and a sky that switched off at 0° would flicker as the
/// viewer's sun crosses it.
const TWILIGHT_DEG: f64 = 6.0;

/// The Perez coefficients `A..E` of one quantity.
type Perez = [f64; 5];

/// A Preetham sky for one sun and turbidity, ready to evaluate.
#[derive(Clone, Debug)]
pub struct Preetham {
    /// Unit vector towards the sun.
    sun: [f64; 3],
    /// Perez coefficients of Y, x, y.
    perez: [Perez; 3],
    /// Per quantity the zenith's value (luminance in kcd/m², chromaticity
    /// x, y) over `F(0, θs)`, `θs` the sun's zenith angle as the fits use
    /// it (at most π/2): the model's normalisation.
    scale: [f64; 3],
    /// 1 with the sun above the horizon, falling to 0 over the twilight.
    fade: f64,
    turbidity: f64,
}

fn perez_f(c: &Perez, cos_theta: f64, gamma: f64) -> f64 {
    let [a, b, cc, d, e] = *c;
    let cos_g = gamma.cos();
    // cos θ = 0 at the horizon: B < 0 for every valid turbidity, so the
    // exponent goes to −∞ and the term to 0 (not NaN).
    (1.0 + a * (b / cos_theta.max(0.0)).exp()) * (1.0 + cc * (d * gamma).exp() + e * cos_g * cos_g)
}

/// CIE xyY to linear sRGB (D65; IEC 61966-2-1's matrix).
fn xyy_to_rgb(x: f64, y: f64, lum: f64) -> [f64; 3] {
    if y <= 0.0 {
        return [0.0; 3];
    }
    let big_x = x * lum / y;
    let big_z = (1.0 - x - y) * lum / y;
    [
        3.2406 * big_x - 1.5372 * lum - 0.4986 * big_z,
        -0.9689 * big_x + 1.8758 * lum + 0.0415 * big_z,
        0.0557 * big_x - 0.2040 * lum + 1.0570 * big_z,
    ]
}

impl Preetham {
    /// The sky for the unit vector `sun` (towards the sun, `+y` up) and
    /// turbidity `t` (within [`TURBIDITY`], checked by the caller).
    pub fn new(sun: [f64; 3], t: f64) -> Preetham {
        let elevation = sun[1].clamp(-1.0, 1.0).asin();
        let fade = ((elevation.to_degrees() + TWILIGHT_DEG) / TWILIGHT_DEG).clamp(0.0, 1.0);
        let theta_s = (PI / 2.0 - elevation).min(PI / 2.0);
        // Zenith luminance (kcd/m²), Preetham et al. A.2.
        let chi = (4.0 / 9.0 - t / 120.0) * (PI - 2.0 * theta_s);
        let y_z = (4.0453 * t - 4.9710) * chi.tan() - 0.2155 * t + 2.4192;
        // Zenith chromaticity: [T², T, 1] · M · [θ³, θ², θ, 1].
        let th = [theta_s.powi(3), theta_s.powi(2), theta_s, 1.0];
        let chroma = |m: [[f64; 4]; 3]| {
            let row = |r: [f64; 4]| r.iter().zip(th).map(|(a, b)| a * b).sum::<f64>();
            t * t * row(m[0]) + t * row(m[1]) + row(m[2])
        };
        let x_z = chroma([
            [0.00166, -0.00375, 0.00209, 0.0],
            [-0.02903, 0.06377, -0.03202, 0.00394],
            [0.11693, -0.21196, 0.06052, 0.25886],
        ]);
        let yy_z = chroma([
            [0.00275, -0.00610, 0.00317, 0.0],
            [-0.04214, 0.08970, -0.04153, 0.00516],
            [0.15346, -0.26756, 0.06670, 0.26688],
        ]);
        let perez = [
            [
                0.1787 * t - 1.4630,
                -0.3554 * t + 0.4275,
                -0.0227 * t + 5.3251,
                0.1206 * t - 2.5771,
                -0.0670 * t + 0.3703,
            ],
            [
                -0.0193 * t - 0.2592,
                -0.0665 * t + 0.0008,
                -0.0004 * t + 0.2125,
                -0.0641 * t - 0.8989,
                -0.0033 * t + 0.0452,
            ],
            [
                -0.0167 * t - 0.2608,
                -0.0950 * t + 0.0092,
                -0.0079 * t + 0.2102,
                -0.0441 * t - 1.6537,
                -0.0109 * t + 0.0529,
            ],
        ];
        let norm = 1.0 / sun.iter().map(|v| v * v).sum::<f64>().sqrt();
        let zenith = [y_z.max(0.0), x_z, yy_z];
        Preetham {
            sun: sun.map(|v| v * norm),
            scale: std::array::from_fn(|k| zenith[k] / perez_f(&perez[k], 1.0, theta_s)),
            perez,
            fade,
            turbidity: t,
        }
    }

    /// The sky's radiance from direction `d` (unit, towards the sky), in
    /// W/(m² sr), linear sRGB; 0 below the horizon (the ground is the
    /// scene's own).
    pub fn radiance(&self, d: [f64; 3]) -> [f64; 3] {
        let cos_theta = d[1];
        if cos_theta <= 0.0 || self.fade == 0.0 {
            return [0.0; 3];
        }
        let cos_gamma =
            (d[0] * self.sun[0] + d[1] * self.sun[1] + d[2] * self.sun[2]).clamp(-1.0, 1.0);
        let gamma = cos_gamma.acos();
        let v: [f64; 3] =
            std::array::from_fn(|k| self.scale[k] * perez_f(&self.perez[k], cos_theta, gamma));
        let rgb = xyy_to_rgb(v[1], v[2], v[0] * 1000.0 / LM_PER_W);
        rgb.map(|c| (c * self.fade).max(0.0))
    }

    /// The sun's irradiance on a surface facing it, W/m², linear sRGB: the
    /// top-of-atmosphere illuminance (white) times the transmittance
    /// `exp(−m (τ_R + τ_a))` at 680, 550 and 440 nm — Rayleigh
    /// `τ_R = 0.008735 λ^−4.08` and Ångström aerosols `τ_a = β λ^−1.3` with
    /// `β = 0.04608 T − 0.04586` (λ in µm; Preetham et al. A.1), along
    /// Kasten's relative air mass `m = 1 / (cos θ + 0.15 (93.885 − θ°)^−1.253)`.
    /// Zero with the sun at or below the horizon.
    pub fn sun_irradiance(&self) -> [f64; 3] {
        if self.sun[1] <= 0.0 {
            return [0.0; 3];
        }
        let theta = self.sun[1].acos();
        let m = 1.0 / (theta.cos() + 0.15 * (93.885 - theta.to_degrees()).powf(-1.253));
        let beta = 0.04608 * self.turbidity - 0.04586;
        let top = SUN_ILLUMINANCE_TOP / LM_PER_W;
        [0.680f64, 0.550, 0.440].map(|l| {
            let tau = 0.008735 * l.powf(-4.08) + beta * l.powf(-1.3);
            top * (-m * tau).exp()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn luminance(c: [f64; 3]) -> f64 {
        0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
    }

    fn unit(elevation_deg: f64, azimuth_deg: f64) -> [f64; 3] {
        let (e, a) = (elevation_deg.to_radians(), azimuth_deg.to_radians());
        [e.cos() * a.sin(), e.sin(), -e.cos() * a.cos()]
    }

    /// The zenith's luminance is the paper's fit, whatever the conversion
    /// (`Y_z` at T = 3, sun at 30° elevation, 1000/683 W per kcd), and its
    /// colour is a sky's: blue over red.
    #[test]
    fn the_zenith_is_the_fit_and_blue() {
        let s = Preetham::new(unit(30.0, 0.0), 3.0);
        let chi = (4.0 / 9.0 - 3.0 / 120.0) * (PI - 2.0 * 60f64.to_radians());
        let y_z = (4.0453 * 3.0 - 4.9710) * chi.tan() - 0.2155 * 3.0 + 2.4192;
        let z = s.radiance([0.0, 1.0, 0.0]);
        let lum = luminance(z);
        assert!(
            (lum - y_z * 1000.0 / 683.0).abs() < 2e-3 * lum,
            "{lum} vs {}",
            y_z * 1000.0 / 683.0
        );
        assert!(z[2] > z[0], "{z:?}");
    }

    /// Brighter towards the sun than away from it at the same elevation;
    /// black below the horizon and with the sun past the twilight.
    #[test]
    fn the_sun_side_is_brighter_and_night_is_black() {
        let s = Preetham::new(unit(20.0, 0.0), 3.0);
        let near = luminance(s.radiance(unit(20.0, 20.0)));
        let far = luminance(s.radiance(unit(20.0, 180.0)));
        assert!(near > 2.0 * far, "{near} {far}");
        assert_eq!(s.radiance(unit(-5.0, 0.0)), [0.0; 3]);
        let night = Preetham::new(unit(-7.0, 0.0), 3.0);
        assert_eq!(night.radiance([0.0, 1.0, 0.0]), [0.0; 3]);
        assert_eq!(night.sun_irradiance(), [0.0; 3]);
        let dusk = Preetham::new(unit(-3.0, 0.0), 3.0);
        let l = luminance(dusk.radiance([0.0, 1.0, 0.0]));
        assert!(l > 0.0 && l.is_finite(), "{l}");
    }

    /// The sun at the zenith through a clear atmosphere: about 100 klx on
    /// the ground (the handbooks' 90–110 klx at T = 2–3), yellower than
    /// white; lower and redder at 10° elevation; dimmer with haze.
    #[test]
    fn the_sun_is_about_a_hundred_kilolux_and_reddens_low() {
        let high = Preetham::new([0.0, 1.0, 0.0], 2.5).sun_irradiance();
        let lux = luminance(high) * 683.0;
        assert!((85e3..115e3).contains(&lux), "{lux}");
        assert!(high[0] > high[2], "{high:?}");
        let low = Preetham::new(unit(10.0, 0.0), 2.5).sun_irradiance();
        assert!(luminance(low) < 0.7 * luminance(high));
        assert!(low[0] / low[2] > high[0] / high[2]);
        let hazy = Preetham::new([0.0, 1.0, 0.0], 8.0).sun_irradiance();
        assert!(luminance(hazy) < luminance(high));
    }

    /// Every direction over a range of suns and turbidities gives finite,
    /// non-negative radiance.
    #[test]
    fn radiance_is_finite_and_non_negative_everywhere() {
        for t in [2.0, 3.0, 6.0, 10.0] {
            for e in [-10.0, -3.0, 0.0, 1.0, 15.0, 45.0, 89.0, 90.0] {
                let s = Preetham::new(unit(e, 30.0), t);
                for k in 0..500 {
                    let y = 1.0 - 2.0 * (k as f64 + 0.5) / 500.0;
                    let phi = k as f64 * 2.399_963;
                    let r = (1.0 - y * y).sqrt();
                    let l = s.radiance([r * phi.cos(), y, r * phi.sin()]);
                    assert!(
                        l.iter().all(|v| v.is_finite() && *v >= 0.0),
                        "{t} {e} {l:?}"
                    );
                }
            }
        }
    }
}
