//! The list of drops to render and the `runs.csv` manifest (SPEC §4).
//!
//! A campaign is the paper's grid R ∈ {3, 4, 4.5, 5, 7} mm × H ∈ {1.5, 3, 6,
//! 12, 25, 50} cm (Maruoka 2019, Figs. 3–4), each repeated `repeats` times, or
//! an explicit list of `R:H` pairs. Run names read `R4.5mm_H12cm_01`.

/// The paper's sphere radii, mm.
pub const PAPER_RADII_MM: [f64; 5] = [3.0, 4.0, 4.5, 5.0, 7.0];
/// The paper's drop heights, cm.
pub const PAPER_HEIGHTS_CM: [f64; 6] = [1.5, 3.0, 6.0, 12.0, 25.0, 50.0];

/// One drop to render.
#[derive(Debug, Clone, PartialEq)]
pub struct DropSpec {
    /// Folder and file-name prefix.
    pub run: String,
    /// Sphere radius R, mm.
    pub radius_mm: f64,
    /// Fall height of the sphere's lowest point to the surface, cm.
    pub height_cm: f64,
    /// Position in the campaign (0-based); sets the trigger's wall-clock time.
    pub index: usize,
    /// The camera set-up it is filmed with: one per radius and repeat
    /// (`cam_R4.5mm_01`), as when the camera is refocused and zoomed for
    /// each sphere size.
    pub setup: String,
}

/// `R<r>mm_H<h>cm_<repeat:02>`, numbers in their shortest form.
pub fn run_name(radius_mm: f64, height_cm: f64, repeat: usize) -> String {
    format!("R{radius_mm}mm_H{height_cm}cm_{repeat:02}")
}

/// `cam_R<r>mm_<repeat:02>`: the set-up of a sphere radius in one repeat.
pub fn setup_name(radius_mm: f64, repeat: usize) -> String {
    format!("cam_R{radius_mm}mm_{repeat:02}")
}

/// Every radius × every height × `repeats`, radius-major.
pub fn grid(radii_mm: &[f64], heights_cm: &[f64], repeats: usize) -> Vec<DropSpec> {
    let mut out = Vec::new();
    for &r in radii_mm {
        for &h in heights_cm {
            for rep in 1..=repeats {
                out.push(DropSpec {
                    run: run_name(r, h, rep),
                    radius_mm: r,
                    height_cm: h,
                    index: out.len(),
                    setup: setup_name(r, rep),
                });
            }
        }
    }
    out
}

/// Explicit `(R mm, H cm)` pairs; a pair given twice gets repeat number 2.
pub fn from_pairs(pairs: &[(f64, f64)]) -> Vec<DropSpec> {
    let mut out: Vec<DropSpec> = Vec::new();
    for &(r, h) in pairs {
        let rep = 1 + out
            .iter()
            .filter(|d| d.radius_mm == r && d.height_cm == h)
            .count();
        out.push(DropSpec {
            run: run_name(r, h, rep),
            radius_mm: r,
            height_cm: h,
            index: out.len(),
            setup: setup_name(r, rep),
        });
    }
    out
}

/// Parse `R:H` (sphere radius in mm, drop height in cm), e.g. `4.5:12`.
pub fn parse_pair(text: &str) -> Result<(f64, f64), String> {
    let (r, h) = text
        .split_once(':')
        .ok_or_else(|| format!("`{text}`: expected RADIUS_MM:HEIGHT_CM, e.g. 4.5:12"))?;
    let num = |s: &str, what: &str| -> Result<f64, String> {
        s.trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite() && *v > 0.0)
            .ok_or_else(|| format!("`{text}`: {what} `{s}` must be a number > 0"))
    };
    Ok((num(r, "radius")?, num(h, "height")?))
}

/// A row of a `real` campaign's `runs.csv`: what an experimenter knows
/// (no scale, no surface row; the frame rate is in the PCC XML), plus the
/// true scale when `--manifest-scale` asks for it.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SetupManifestRow {
    /// The run's name.
    pub run: String,
    /// The run's folder, relative to the manifest.
    pub path: std::path::PathBuf,
    /// Sphere radius R, mm.
    pub sphere_radius_mm: f64,
    /// Fall height of the sphere's lowest point to the surface, cm.
    pub drop_height_cm: f64,
    /// The camera set-up the run was filmed with.
    pub setup: String,
    /// The true scale, mm per px, with `--manifest-scale`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mm_per_px: Option<f64>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_paper_grid_has_thirty_drops_per_repeat_with_unique_names() {
        let g = grid(&PAPER_RADII_MM, &PAPER_HEIGHTS_CM, 2);
        assert_eq!(g.len(), 60);
        let mut names: Vec<_> = g.iter().map(|d| d.run.clone()).collect();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), 60);
        assert_eq!(g[0].run, "R3mm_H1.5cm_01");
        assert_eq!(g[59].run, "R7mm_H50cm_02");
    }

    #[test]
    fn pairs_parse_and_reject_nonsense() {
        assert_eq!(parse_pair("4.5:12"), Ok((4.5, 12.0)));
        assert!(parse_pair("4.5").is_err());
        assert!(parse_pair("-1:3").unwrap_err().contains("radius"));
        let d = from_pairs(&[(3.0, 3.0), (3.0, 3.0)]);
        assert_eq!(d[1].run, "R3mm_H3cm_02");
    }
}
