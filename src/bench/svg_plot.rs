//! Log–log scatter plots as SVG, for the benchmark reports: decade grid
//! lines and labels on both axes, one colour per series, a legend. Written
//! by hand: circles, lines and text need no plotting crate, and an SVG is
//! shown by any browser and by the repository's Markdown.

use std::fmt::Write as _;

/// One series: name, CSS colour, points `(x, y, label)` (the label is the
/// point's tooltip).
pub struct Series {
    pub name: String,
    pub colour: String,
    pub points: Vec<(f64, f64, String)>,
}

const W: f64 = 720.0;
const H: f64 = 480.0;
const LEFT: f64 = 80.0;
const RIGHT: f64 = 20.0;
const TOP: f64 = 40.0;
const BOTTOM: f64 = 60.0;

/// Escapes text for SVG.
fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The decades covering `lo..hi` (positive values).
fn decades(lo: f64, hi: f64) -> (i32, i32) {
    let a = lo.log10().floor() as i32;
    let b = hi.log10().ceil() as i32;
    (a, if b > a { b } else { a + 1 })
}

/// A log–log scatter of `series` (non-positive and non-finite points are
/// left out).
pub fn scatter(title: &str, x_label: &str, y_label: &str, series: &[Series]) -> String {
    let ok = |v: f64| v.is_finite() && v > 0.0;
    let all: Vec<(f64, f64)> = series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| (p.0, p.1)))
        .filter(|p| ok(p.0) && ok(p.1))
        .collect();
    let (xl, xh) = all
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.0), b.max(p.0)));
    let (yl, yh) = all
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.1), b.max(p.1)));
    let (xd0, xd1) = if all.is_empty() {
        (0, 1)
    } else {
        decades(xl, xh)
    };
    let (yd0, yd1) = if all.is_empty() {
        (0, 1)
    } else {
        decades(yl, yh)
    };
    let pw = W - LEFT - RIGHT;
    let ph = H - TOP - BOTTOM;
    let px = |x: f64| LEFT + pw * (x.log10() - xd0 as f64) / (xd1 - xd0) as f64;
    let py = |y: f64| TOP + ph * (1.0 - (y.log10() - yd0 as f64) / (yd1 - yd0) as f64);
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="{W}" height="{H}" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="{}" y="22" text-anchor="middle" font-size="15">{}</text>"#,
        W / 2.0,
        esc(title)
    );
    for d in xd0..=xd1 {
        let x = LEFT + pw * (d - xd0) as f64 / (xd1 - xd0) as f64;
        let _ = writeln!(
            s,
            r##"<line x1="{x:.1}" y1="{TOP}" x2="{x:.1}" y2="{:.1}" stroke="#ddd"/><text x="{x:.1}" y="{:.1}" text-anchor="middle">1e{d}</text>"##,
            TOP + ph,
            TOP + ph + 16.0
        );
    }
    for d in yd0..=yd1 {
        let y = TOP + ph * (1.0 - (d - yd0) as f64 / (yd1 - yd0) as f64);
        let _ = writeln!(
            s,
            r##"<line x1="{LEFT}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="#ddd"/><text x="{:.1}" y="{:.1}" text-anchor="end">1e{d}</text>"##,
            LEFT + pw,
            LEFT - 6.0,
            y + 4.0
        );
    }
    let _ = writeln!(
        s,
        r##"<rect x="{LEFT}" y="{TOP}" width="{pw}" height="{ph}" fill="none" stroke="#444"/>"##
    );
    let _ = writeln!(
        s,
        r#"<text x="{:.1}" y="{:.1}" text-anchor="middle">{}</text>"#,
        LEFT + pw / 2.0,
        H - 15.0,
        esc(x_label)
    );
    let _ = writeln!(
        s,
        r#"<text x="18" y="{:.1}" text-anchor="middle" transform="rotate(-90 18 {:.1})">{}</text>"#,
        TOP + ph / 2.0,
        TOP + ph / 2.0,
        esc(y_label)
    );
    for (k, se) in series.iter().enumerate() {
        for (x, y, label) in &se.points {
            if ok(*x) && ok(*y) {
                let _ = writeln!(
                    s,
                    r#"<circle cx="{:.1}" cy="{:.1}" r="4" fill="{}" fill-opacity="0.8"><title>{}</title></circle>"#,
                    px(*x),
                    py(*y),
                    se.colour,
                    esc(label)
                );
            }
        }
        let ly = TOP + 14.0 + 16.0 * k as f64;
        let _ = writeln!(
            s,
            r#"<circle cx="{:.1}" cy="{:.1}" r="4" fill="{}"/><text x="{:.1}" y="{:.1}">{}</text>"#,
            LEFT + 12.0,
            ly - 4.0,
            se.colour,
            LEFT + 22.0,
            ly,
            esc(&se.name)
        );
    }
    s += "</svg>\n";
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scatter_places_points_by_decade_and_skips_bad_ones() {
        let svg = scatter(
            "t",
            "x <a>",
            "y",
            &[Series {
                name: "s".into(),
                colour: "red".into(),
                points: vec![
                    (0.01, 10.0, "a".into()),
                    (0.1, 100.0, "b".into()),
                    (-1.0, 5.0, "bad".into()),
                    (f64::NAN, 5.0, "nan".into()),
                ],
            }],
        );
        assert_eq!(
            svg.matches("<circle").count(),
            3,
            "two points and the legend's"
        );
        assert!(svg.contains("x &lt;a&gt;"));
        assert!(svg.contains("1e-2") && svg.contains("1e-1") && svg.contains("1e2"));
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    }
}
