//! Sampled spectra to RGB as Mitsuba 3's RGB variants read them, so that a scene written
//! with `<spectrum value="400:0.34, 404:0.35, ...">` renders in lucent with the colours
//! Mitsuba gives it.
//!
//! A spectrum is integrated against the CIE 1931 colour-matching functions over 360-830 nm
//! (1,000 evenly spaced points, the spectrum linearly interpolated between its samples and
//! zero outside them), the XYZ result taken to linear sRGB. Reflectances and other unitless
//! terms are seen under illuminant D65 (white stays white), emission is not (an
//! equal-energy spectrum comes out slightly pink, as in Mitsuba); a reflectance is clamped
//! to [0, 1], anything else to at least 0. Checked against Mitsuba 3.9.1's own conversions
//! (see the tests).

use glam::Vec3;

/// Samples in the tables below.
const SAMPLES: usize = 95;

/// Shortest and longest wavelength of the tables (nm).
const LAMBDA_MIN: f32 = 360.0;
const LAMBDA_MAX: f32 = 830.0;

/// One over the integral of the CIE ȳ function over 360-830 nm (106.7502, by the quadrature
/// Mitsuba uses for it): an equal-energy spectrum of value one has luminance one.
const Y_NORMALIZATION: f64 = 1.0 / 106.750_2;

/// How a spectrum is used, which decides its conversion.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpectrumUse {
    /// A reflectance (or transmittance): seen under D65, clamped to [0, 1].
    Reflectance,
    /// A unitless term that may exceed one (an index of refraction, an absorption
    /// coefficient): seen under D65, clamped to at least 0.
    Unbounded,
    /// Emitted radiance, intensity or irradiance: not weighted by an illuminant, clamped to
    /// at least 0.
    Emission,
}

/// The CIE 1931 2° standard observer's colour-matching functions x̄, ȳ, z̄ at 360, 365,
/// ..., 830 nm (CIE 015:2004, table T.4), as float32.
#[rustfmt::skip]
const CIE_XYZ: [[f32; 3]; SAMPLES] = [
    [1.299e-04, 3.917e-06, 6.061e-04],
    [2.321e-04, 6.965e-06, 0.001086],
    [4.149e-04, 1.239e-05, 0.001946],
    [7.416e-04, 2.202e-05, 0.003486],
    [0.001368, 3.9e-05, 0.006450001],
    [0.002236, 6.4e-05, 0.01054999],
    [0.004243, 1.2e-04, 0.02005001],
    [0.00765, 2.17e-04, 0.03621],
    [0.01431, 3.96e-04, 0.06785001],
    [0.02319, 6.4e-04, 0.1102],
    [0.04351, 0.00121, 0.2074],
    [0.07763, 0.00218, 0.3713],
    [0.13438, 0.004, 0.6456],
    [0.21477, 0.0073, 1.0390501],
    [0.2839, 0.0116, 1.3856],
    [0.3285, 0.01684, 1.62296],
    [0.34828, 0.023, 1.74706],
    [0.34806, 0.0298, 1.7826],
    [0.3362, 0.038, 1.77211],
    [0.3187, 0.048, 1.7441],
    [0.2908, 0.06, 1.6692],
    [0.2511, 0.0739, 1.5281],
    [0.19536, 0.09098, 1.28764],
    [0.1421, 0.1126, 1.0419],
    [0.09564, 0.13902, 0.8129501],
    [0.05795001, 0.1693, 0.6162],
    [0.03201, 0.20802, 0.46518],
    [0.0147, 0.2586, 0.3533],
    [0.0049, 0.323, 0.272],
    [0.0024, 0.4073, 0.2123],
    [0.0093, 0.503, 0.1582],
    [0.0291, 0.6082, 0.1117],
    [0.06327, 0.71, 0.07824999],
    [0.1096, 0.7932, 0.05725001],
    [0.1655, 0.862, 0.04216],
    [0.2257499, 0.9148501, 0.02984],
    [0.2904, 0.954, 0.0203],
    [0.3597, 0.9803, 0.0134],
    [0.4334499, 0.9949501, 0.008749999],
    [0.5120501, 1.0, 0.005749999],
    [0.5945, 0.995, 0.0039],
    [0.6784, 0.9786, 0.002749999],
    [0.7621, 0.952, 0.0021],
    [0.8425, 0.9154, 0.0018],
    [0.9163, 0.87, 0.001650001],
    [0.9786, 0.8163, 0.0014],
    [1.0263, 0.757, 0.0011],
    [1.0567, 0.6949, 0.001],
    [1.0622, 0.631, 8.0e-04],
    [1.0456, 0.5668, 6.0e-04],
    [1.0026, 0.503, 3.4e-04],
    [0.9384, 0.4412, 2.4e-04],
    [0.8544499, 0.381, 1.9e-04],
    [0.7514, 0.321, 1.0e-04],
    [0.6424, 0.265, 4.999999e-05],
    [0.5419, 0.217, 3.0e-05],
    [0.4479, 0.175, 2.0e-05],
    [0.3608, 0.1382, 1.0e-05],
    [0.2835, 0.107, 0.0],
    [0.2187, 0.0816, 0.0],
    [0.1649, 0.061, 0.0],
    [0.1212, 0.04458, 0.0],
    [0.0874, 0.032, 0.0],
    [0.0636, 0.0232, 0.0],
    [0.04677, 0.017, 0.0],
    [0.0329, 0.01192, 0.0],
    [0.0227, 0.00821, 0.0],
    [0.01584, 0.005723, 0.0],
    [0.01135916, 0.004102, 0.0],
    [0.008110916, 0.002929, 0.0],
    [0.005790346, 0.002091, 0.0],
    [0.004109457, 0.001484, 0.0],
    [0.002899327, 0.001047, 0.0],
    [0.00204919, 7.4e-04, 0.0],
    [0.001439971, 5.2e-04, 0.0],
    [9.999493e-04, 3.611e-04, 0.0],
    [6.900786e-04, 2.492e-04, 0.0],
    [4.760213e-04, 1.719e-04, 0.0],
    [3.323011e-04, 1.2e-04, 0.0],
    [2.348261e-04, 8.48e-05, 0.0],
    [1.661505e-04, 6.0e-05, 0.0],
    [1.17413e-04, 4.24e-05, 0.0],
    [8.307527e-05, 3.0e-05, 0.0],
    [5.870652e-05, 2.12e-05, 0.0],
    [4.150994e-05, 1.499e-05, 0.0],
    [2.935326e-05, 1.06e-05, 0.0],
    [2.067383e-05, 7.4657e-06, 0.0],
    [1.455977e-05, 5.2578e-06, 0.0],
    [1.025398e-05, 3.7029e-06, 0.0],
    [7.221456e-06, 2.6078e-06, 0.0],
    [5.085868e-06, 1.8366e-06, 0.0],
    [3.581652e-06, 1.2934e-06, 0.0],
    [2.522525e-06, 9.1093e-07, 0.0],
    [1.776509e-06, 6.4153e-07, 0.0],
    [1.251141e-06, 4.5181e-07, 0.0],
];

/// CIE standard illuminant D65's relative spectral power at the same wavelengths (CIE
/// 015:2004, table T.1), scaled so that a white surface under it has luminance one
/// with [`Y_NORMALIZATION`] (the scale Mitsuba 3's `d65` spectrum carries).
#[rustfmt::skip]
const D65: [f32; SAMPLES] = [
    0.47110626, 0.49863625, 0.52616626, 0.5154912, 0.5048162, 0.5284158,
    0.55201644, 0.69397265, 0.8359299, 0.880027, 0.92412513, 0.9339526,
    0.9437802, 0.9096904, 0.8756016, 0.9674353, 1.05927, 1.1205949,
    1.1819298, 1.1859906, 1.1900512, 1.1751417, 1.1602424, 1.1656061,
    1.17097, 1.1350498, 1.0991297, 1.1018671, 1.1046146, 1.0967761,
    1.0889375, 1.073725, 1.0585124, 1.0731492, 1.0877961, 1.0712098,
    1.0546235, 1.0528052, 1.0509971, 1.0305623, 1.0101273, 0.99161273,
    0.9730981, 0.9703394, 0.9675808, 0.9317092, 0.8958375, 0.9025074,
    0.9091773, 0.9071206, 0.905065, 0.8954668, 0.88586855, 0.86359423,
    0.84132093, 0.8433947, 0.8454686, 0.82692057, 0.8083726, 0.8093211,
    0.8102696, 0.8206901, 0.8311106, 0.8109403, 0.7907702, 0.7475215,
    0.7042739, 0.71380854, 0.72334313, 0.7371808, 0.7510196, 0.68664926,
    0.62227887, 0.6641062, 0.7059335, 0.7322039, 0.7584743, 0.70042026,
    0.64236724, 0.5556246, 0.46888295, 0.5718513, 0.6748196, 0.65753335,
    0.640247, 0.64489967, 0.6495523, 0.6250456, 0.6005399, 0.56269544,
    0.5248521, 0.5525376, 0.5802232, 0.59472764, 0.6092331,
];

/// A table at `lambda` (nm), linearly interpolated; zero outside 360-830 nm.
fn lerp_table<const K: usize>(table: &[[f32; K]; SAMPLES], lambda: f64) -> [f64; K] {
    let x = (lambda - f64::from(LAMBDA_MIN)) / 5.0;
    if !(0.0..=(SAMPLES - 1) as f64).contains(&x) {
        return [0.0; K];
    }
    let i = (x as usize).min(SAMPLES - 2);
    let f = x - i as f64;
    std::array::from_fn(|k| f64::from(table[i][k]) * (1.0 - f) + f64::from(table[i + 1][k]) * f)
}

/// Linear XYZ (D65 white) to linear sRGB (IEC 61966-2-1).
fn xyz_to_srgb(c: [f64; 3]) -> Vec3 {
    Vec3::new(
        (3.240_479 * c[0] - 1.537_150 * c[1] - 0.498_535 * c[2]) as f32,
        (-0.969_256 * c[0] + 1.875_991 * c[1] + 0.041_556 * c[2]) as f32,
        (0.055_648 * c[0] - 0.204_043 * c[1] + 1.057_311 * c[2]) as f32,
    )
}

/// The linear sRGB colour of the spectrum with `values` at `wavelengths` (nm, increasing),
/// used as `usage` says. Returns `None` for lists that are empty, of different lengths or
/// not increasing.
#[must_use]
pub fn spectrum_to_rgb(wavelengths: &[f32], values: &[f32], usage: SpectrumUse) -> Option<Vec3> {
    if wavelengths.is_empty() || wavelengths.len() != values.len() || wavelengths.windows(2).any(|w| w[0] >= w[1]) {
        return None;
    }
    let d65: [[f32; 1]; SAMPLES] = std::array::from_fn(|i| [D65[i]]);
    let (lo, hi) = (f64::from(wavelengths[0]), f64::from(wavelengths[wavelengths.len() - 1]));
    let steps = 1000;
    let mut xyz = [0.0f64; 3];
    let mut cell = 0;
    for i in 0..steps {
        let x = f64::from(LAMBDA_MIN) + i as f64 / (steps - 1) as f64 * f64::from(LAMBDA_MAX - LAMBDA_MIN);
        if x < lo || x > hi {
            continue;
        }
        // The last sample at or before x (one sample: its value everywhere in range).
        while cell + 2 < wavelengths.len() && f64::from(wavelengths[cell + 1]) <= x {
            cell += 1;
        }
        let y = if wavelengths.len() == 1 {
            f64::from(values[0])
        } else {
            let (x0, x1) = (f64::from(wavelengths[cell]), f64::from(wavelengths[cell + 1]));
            let (y0, y1) = (f64::from(values[cell]), f64::from(values[cell + 1]));
            y0 + (y1 - y0) * (x - x0) / (x1 - x0)
        };
        let w = match usage {
            SpectrumUse::Emission => y,
            _ => y * lerp_table(&d65, x)[0],
        };
        let c = lerp_table(&CIE_XYZ, x);
        for k in 0..3 {
            xyz[k] += c[k] * w;
        }
    }
    let scale = f64::from(LAMBDA_MAX - LAMBDA_MIN) / steps as f64 * Y_NORMALIZATION;
    let rgb = xyz_to_srgb(xyz.map(|c| c * scale));
    Some(match usage {
        SpectrumUse::Reflectance => rgb.clamp(Vec3::ZERO, Vec3::ONE),
        _ => rgb.max(Vec3::ZERO),
    })
}

/// The colour of an equal-energy spectrum of value one as emission (Mitsuba's reading of
/// `<spectrum value="1"/>` in an emitter): a little pink, since sRGB's white is D65. The
/// numbers are Mitsuba 3.9.1's, which computes this one by another quadrature than
/// [`spectrum_to_rgb`]'s (that gives 1.204884, 0.948229, 0.909267).
pub const EQUAL_ENERGY_EMISSION: Vec3 = Vec3::new(1.204_794, 0.948_291, 0.908_916);

/// Planck's law: the spectral radiance of a black body at `temperature` kelvin, in
/// W m⁻² sr⁻¹ nm⁻¹, at 360, 361, ..., 830 nm (Mitsuba's `blackbody` spectrum, with its
/// constants). `None` for a temperature that is not positive and finite.
#[must_use]
pub fn blackbody(temperature: f32) -> Option<(Vec<f32>, Vec<f32>)> {
    if !(temperature > 0.0 && temperature.is_finite()) {
        return None;
    }
    const C: f64 = 2.997_924_58e8; // speed of light, m/s
    const H: f64 = 6.626_070_04e-34; // Planck's constant, J s
    const K: f64 = 1.380_648_52e-23; // Boltzmann's constant, J/K
    let t = f64::from(temperature);
    let w: Vec<f32> = (LAMBDA_MIN as u32..=LAMBDA_MAX as u32).map(|l| l as f32).collect();
    let v = w
        .iter()
        .map(|&l| {
            let l = f64::from(l) * 1e-9;
            // (Per metre of wavelength, then per nanometre.)
            (2.0 * H * C * C / (l.powi(5) * ((H * C / (l * K * t)).exp_m1())) * 1e-9) as f32
        })
        .collect();
    Some((w, v))
}

/// Parses `400:0.34, 404:0.35, ...` into wavelengths and values; `Err` names the bad
/// pair.
pub fn parse_pairs(s: &str) -> Result<(Vec<f32>, Vec<f32>), String> {
    let (mut w, mut v) = (Vec::new(), Vec::new());
    for pair in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let (a, b) = pair.split_once(':').ok_or_else(|| format!("'{pair}' is not wavelength:value"))?;
        let (Ok(a), Ok(b)) = (a.trim().parse::<f32>(), b.trim().parse::<f32>()) else {
            return Err(format!("'{pair}' is not two numbers"));
        };
        if !a.is_finite() || !b.is_finite() {
            return Err(format!("'{pair}' is not finite"));
        }
        w.push(a);
        v.push(b);
    }
    if w.windows(2).any(|p| p[0] >= p[1]) {
        return Err("wavelengths must increase".into());
    }
    if w.is_empty() {
        return Err("no wavelength:value pairs".into());
    }
    Ok((w, v))
}

/// Reads an `.spd` file's text: a wavelength and a value per line, `#` comments.
pub fn parse_spd(text: &str) -> Result<(Vec<f32>, Vec<f32>), String> {
    let pairs: Vec<String> = text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .map(|l| l.split_whitespace().collect::<Vec<_>>().join(":"))
        .collect();
    parse_pairs(&pairs.join(","))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Vec3, b: [f32; 3]) {
        let b = Vec3::from(b);
        assert!((a - b).abs().max_element() <= 2e-5 * b.abs().max_element().max(1.0), "{a} vs Mitsuba's {b}");
    }

    /// Mitsuba 3.9.1's (`scalar_rgb`) colours of the same spectra, read back from scenes it
    /// loaded (`mi.traverse`).
    #[test]
    fn spectra_convert_as_mitsuba_converts_them() {
        let r = |w: &[f32], v: &[f32], u| spectrum_to_rgb(w, v, u).expect("valid");
        use SpectrumUse::*;
        close(r(&[400.0, 500.0, 600.0, 700.0], &[0.2, 0.5, 0.8, 0.3], Reflectance), [0.755_029, 0.641_416, 0.323_239]);
        close(r(&[400.0, 500.0, 600.0, 700.0], &[0.2, 0.5, 0.8, 0.3], Emission), [0.886_932, 0.614_419, 0.285_147]);
        close(r(&[400.0, 500.0, 700.0], &[0.9, 0.1, 0.95], Reflectance), [0.736_634, 0.235_347, 0.481_379]);
        close(r(&[400.0, 700.0], &[0.5, 0.7], Reflectance), [0.658_501, 0.595_169, 0.524_663]);
        close(r(&[400.0, 700.0], &[1.5, 2.0], Unbounded), [1.895_09, 1.737_86, 1.560_38]);
        close(r(&[400.0, 700.0], &[3.0, 4.0], Unbounded), [3.790_17, 3.475_72, 3.120_77]);
        close(r(&[400.0, 700.0], &[10.0, 20.0], Emission), [21.4, 14.042_4, 10.171_4]);
        close(r(&[400.0, 700.0], &[1.0, 1.0], Emission), [1.199_69, 0.949_52, 0.903_443]);
        close(r(&[400.0, 500.0, 700.0], &[0.0, 8.0, 0.0], Emission), [2.742_46, 6.405_56, 3.618_23]);
        // Out of gamut: a reflectance is clamped.
        close(r(&[400.0, 700.0], &[1.5, 1.5], Reflectance), [1.0, 1.0, 1.0]);
        // `<spectrum value="5"/>` in an emitter
        close(EQUAL_ENERGY_EMISSION * 5.0, [6.023_97, 4.741_46, 4.544_58]);
        let list = r(&[LAMBDA_MIN, LAMBDA_MAX], &[1.0, 1.0], Emission);
        assert!((list - EQUAL_ENERGY_EMISSION).abs().max_element() < 5e-4, "{list}");
        // White under D65 stays white.
        close(r(&[360.0, 830.0], &[1.0, 1.0], Reflectance), [0.998_983, 0.998_872, 0.998_802]);
    }

    #[test]
    fn bad_lists_are_refused() {
        assert!(spectrum_to_rgb(&[], &[], SpectrumUse::Emission).is_none());
        assert!(spectrum_to_rgb(&[500.0, 400.0], &[1.0, 1.0], SpectrumUse::Emission).is_none());
        assert!(parse_pairs("400:1, 500").is_err());
        assert!(parse_pairs("400:1, 300:2").is_err());
        assert!(parse_pairs("400:x").is_err());
        assert_eq!(parse_pairs(" 400:1 ,500:2,").expect("ok"), (vec![400.0, 500.0], vec![1.0, 2.0]));
        assert_eq!(parse_spd("# comment\n400 1\n\n500  2\n").expect("ok"), (vec![400.0, 500.0], vec![1.0, 2.0]));
    }
}
