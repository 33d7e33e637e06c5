//! [`RawConfig::validate`]: each table of the file checked and converted to
//! SI, one function a table. An error names the key, the value and what is
//! allowed.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use super::error::ConfigError;
use super::raw::{RawCamera, RawConfig, RawDetect, RawInput, RawOutput, RawSphere, RawSurface};
use super::settings::{
    CameraConfig, CommandLineValues, DetectConfig, InputConfig, OutputConfig, PipelineConfig,
    SphereConfig, Surface, DEFAULT_DISTORTION_BOUND_PX,
};

struct Checker<'a> {
    path: &'a Path,
}

impl Checker<'_> {
    fn invalid(&self, key: &str, value: impl ToString, allowed: &str) -> ConfigError {
        ConfigError::Invalid {
            path: self.path.to_path_buf(),
            key: key.to_string(),
            value: value.to_string(),
            allowed: allowed.to_string(),
        }
    }

    /// A finite number strictly above zero.
    fn positive(&self, key: &str, v: f64) -> Result<f64, ConfigError> {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(self.invalid(key, v, "must be a finite number greater than 0"))
        }
    }

    /// A number within its physical range ([`crate::util::ranges`]).
    fn ranged(
        &self,
        key: &str,
        range: crate::util::ranges::Range,
        v: f64,
    ) -> Result<f64, ConfigError> {
        let v = self.positive(key, v)?;
        range
            .check(v)
            .map_err(|allowed| self.invalid(key, crate::util::ranges::show(v), &allowed))
    }

    fn ranged_opt(
        &self,
        key: &str,
        range: crate::util::ranges::Range,
        v: Option<f64>,
    ) -> Result<Option<f64>, ConfigError> {
        v.map(|v| self.ranged(key, range, v)).transpose()
    }

    /// A path without a control character (a newline in `[output] dir`
    /// would reach a Slurm script as a command).
    fn path(&self, key: &str, p: PathBuf) -> Result<PathBuf, ConfigError> {
        let text = p.to_string_lossy();
        if text
            .chars()
            .any(|c| c.is_control() || crate::util::text::is_format(c))
        {
            return Err(self.invalid(
                key,
                format!("{:?}", crate::util::text::one_line(&text)),
                "must be a path without control or invisible format characters",
            ));
        }
        Ok(p)
    }
}

impl RawConfig {
    /// Check every value and convert to SI, section by section; the first
    /// value refused is the error.
    pub fn validate(self, path: &Path, base_dir: &Path) -> Result<PipelineConfig, ConfigError> {
        let c = Checker { path };
        let resolve = |p: PathBuf| if p.is_absolute() { p } else { base_dir.join(p) };

        let surfaces = surfaces(&c, self.surface)?;
        let surface = default_surface(&c, self.input.surface.clone(), &surfaces)?;
        let sphere = sphere(&c, &self.sphere)?;
        let camera = camera(&c, &self.camera)?;
        let detect = detect(&c, &self.detect)?;
        let input = input(&c, self.input, surface, &resolve)?;
        let output = output(&c, self.output, &resolve)?;
        Ok(PipelineConfig {
            input,
            camera,
            sphere,
            surfaces,
            detect,
            output,
            command_line: CommandLineValues::default(),
        })
    }
}

/// The `[surface.<name>]` tables, lengths in metres; the paper's PDMS
/// when none is given.
fn surfaces(
    c: &Checker,
    raw: BTreeMap<String, RawSurface>,
) -> Result<BTreeMap<String, Surface>, ConfigError> {
    let mut surfaces = BTreeMap::new();
    for (name, s) in raw {
        let key = |k: &str| format!("surface.{name}.{k}");
        use crate::util::ranges::{MODULUS_PA, PILLAR_MM};
        let modulus_pa = c.ranged(&key("modulus_pa"), MODULUS_PA, s.modulus_pa)?;
        let h = c.ranged(&key("pillar_height_mm"), PILLAR_MM, s.pillar_height_mm)?;
        let b = c.ranged(&key("pillar_width_mm"), PILLAR_MM, s.pillar_width_mm)?;
        let ch = c.ranged(&key("channel_width_mm"), PILLAR_MM, s.channel_width_mm)?;
        let phi = s.solid_fraction.unwrap_or(b / (b + ch));
        if !(phi.is_finite() && phi > 0.0 && phi <= 1.0) {
            return Err(c.invalid(&key("solid_fraction"), phi, "must lie in (0, 1]"));
        }
        surfaces.insert(
            name,
            Surface {
                modulus_pa,
                pillar_height_m: h * 1e-3,
                pillar_width_m: b * 1e-3,
                channel_width_m: ch * 1e-3,
                solid_fraction: phi,
            },
        );
    }
    if surfaces.is_empty() {
        surfaces.insert("pdms".to_string(), Surface::paper_pdms());
    }
    Ok(surfaces)
}

/// `input.surface`: the surface of runs whose manifest row names none, one
/// of `surfaces` (the only one when it is not given).
fn default_surface(
    c: &Checker,
    given: Option<String>,
    surfaces: &BTreeMap<String, Surface>,
) -> Result<String, ConfigError> {
    Ok(match given {
        Some(s) if surfaces.contains_key(&s) => s,
        Some(s) => {
            let known: Vec<_> = surfaces.keys().cloned().collect();
            return Err(c.invalid(
                "input.surface",
                format!("\"{s}\""),
                &format!("must name a [surface.<name>] table: {}", known.join(", ")),
            ));
        }
        None if surfaces.len() == 1 => surfaces.keys().next().cloned().unwrap_or_default(),
        None => {
            return Err(c.invalid(
                "input.surface",
                "(missing)",
                "several [surface.<name>] tables are defined: say which is the default",
            ))
        }
    })
}

/// The `[sphere]` table, the radius in metres.
fn sphere(c: &Checker, s: &RawSphere) -> Result<SphereConfig, ConfigError> {
    use crate::util::ranges::{DENSITY_KG_M3, SPHERE_RADIUS_MM};
    let density = c.ranged(
        "sphere.density_kg_m3",
        DENSITY_KG_M3,
        s.density_kg_m3.unwrap_or(7800.0),
    )?;
    let radius_m = c
        .ranged_opt("sphere.radius_mm", SPHERE_RADIUS_MM, s.radius_mm)?
        .map(|r| r * 1e-3);
    Ok(SphereConfig {
        density_kg_m3: density,
        radius_m,
    })
}

/// The `[camera]` table: frame rate, scale, the lens and the silhouette's
/// edge offset.
fn camera(c: &Checker, cam: &RawCamera) -> Result<CameraConfig, ConfigError> {
    use crate::util::ranges::{FPS, MM_PER_PX};
    let fps = c.ranged_opt("camera.fps", FPS, cam.fps)?;
    let mm_per_px = c.ranged_opt("camera.mm_per_px", MM_PER_PX, cam.mm_per_px)?;
    let distortion_k1_per_px2 = match cam.distortion_k1_per_px2 {
        // |k1| r² above 5 % at 1 000 px from the centre is no lens of
        // this experiment, and the one-term model would not hold.
        Some(k) if !(k.is_finite() && k.abs() <= 5e-8) => {
            return Err(c.invalid(
                "camera.distortion_k1_per_px2",
                k,
                "must be a finite number between -5e-8 and 5e-8 (1/px²)",
            ))
        }
        k => k,
    };
    let distortion_bound_px = cam
        .distortion_bound_px
        .unwrap_or(DEFAULT_DISTORTION_BOUND_PX);
    if !(distortion_bound_px.is_finite() && (0.0..=20.0).contains(&distortion_bound_px)) {
        return Err(c.invalid(
            "camera.distortion_bound_px",
            distortion_bound_px,
            "must be a number of pixels from 0 to 20",
        ));
    }
    if let Some(o) = cam.edge_offset_px {
        if !(o.is_finite() && o.abs() <= 5.0) {
            return Err(c.invalid(
                "camera.edge_offset_px",
                o,
                "must be a number of pixels from -5 to 5",
            ));
        }
    }
    let edge_offset_spread_px = match (cam.edge_offset_spread_px, cam.edge_offset_px) {
        (Some(s), _) if !(s.is_finite() && s > 0.0 && s <= 5.0) => {
            return Err(c.invalid(
                "camera.edge_offset_spread_px",
                s,
                "must be a number of pixels above 0 and at most 5",
            ))
        }
        (Some(s), None) => {
            return Err(c.invalid(
                "camera.edge_offset_spread_px",
                s,
                "is the spread of camera.edge_offset_px, which is not given",
            ))
        }
        (s, _) => s,
    };
    Ok(CameraConfig {
        fps,
        mm_per_px,
        distortion_k1_per_px2,
        distortion_bound_px,
        infer_setups: cam.infer_setups.unwrap_or(true),
        edge_offset_px: cam.edge_offset_px,
        edge_offset_spread_px,
        apply_flips: cam.apply_flips.unwrap_or(true),
        p10_linear: cam.p10_linear.unwrap_or(true),
    })
}

/// The `[detect]` table, each key not given taken from
/// [`DetectConfig::default`].
fn detect(c: &Checker, d: &RawDetect) -> Result<DetectConfig, ConfigError> {
    let defaults = DetectConfig::default();
    let background_frames = d.background_frames.unwrap_or(defaults.background_frames);
    if background_frames == 0 {
        return Err(c.invalid("detect.background_frames", 0, "must be at least 1"));
    }
    let contact_margin_px = d.contact_margin_px.unwrap_or(defaults.contact_margin_px);
    if !(contact_margin_px.is_finite() && contact_margin_px >= 0.0) {
        return Err(c.invalid(
            "detect.contact_margin_px",
            contact_margin_px,
            "must be a finite number ≥ 0",
        ));
    }
    let surface_slope = d.surface_slope.unwrap_or(defaults.surface_slope);
    if !surface_slope.is_finite() || surface_slope.abs() > 0.2 {
        return Err(c.invalid(
            "detect.surface_slope",
            surface_slope,
            "must be a finite tilt in rows per column, |slope| ≤ 0.2",
        ));
    }
    let edge_half_window_px = d
        .edge_half_window_px
        .unwrap_or(defaults.edge_half_window_px);
    if !(3..=30).contains(&edge_half_window_px) {
        return Err(c.invalid(
            "detect.edge_half_window_px",
            edge_half_window_px,
            "must be an integer from 3 to 30",
        ));
    }
    let edge_spacing_px = d.edge_spacing_px.unwrap_or(defaults.edge_spacing_px);
    if !(edge_spacing_px.is_finite() && (1.0..=20.0).contains(&edge_spacing_px)) {
        return Err(c.invalid(
            "detect.edge_spacing_px",
            edge_spacing_px,
            "must be a number of px from 1 to 20",
        ));
    }
    if let Some(r) = d.surface_row_px {
        if !r.is_finite() {
            return Err(c.invalid("detect.surface_row_px", r, "must be a finite row"));
        }
    }
    Ok(DetectConfig {
        background_frames,
        surface_row_px: d.surface_row_px,
        surface_slope,
        contact_margin_px,
        edge_half_window_px,
        edge_spacing_px,
    })
}

/// The `[input]` table's paths, resolved; `surface` is its checked
/// `input.surface` ([`default_surface`]).
fn input(
    c: &Checker,
    raw: RawInput,
    surface: String,
    resolve: &dyn Fn(PathBuf) -> PathBuf,
) -> Result<InputConfig, ConfigError> {
    let manifest = raw
        .manifest
        .map(|p| c.path("input.manifest", p))
        .transpose()?;
    let paths = raw
        .paths
        .into_iter()
        .map(|p| c.path("input.paths", p))
        .collect::<Result<Vec<_>, _>>()?;
    let review = raw.review.map(|p| c.path("input.review", p)).transpose()?;
    Ok(InputConfig {
        manifest: manifest.map(resolve),
        paths: paths.into_iter().map(resolve).collect(),
        surface,
        review: review.map(resolve),
    })
}

/// The `[output]` table, its folder resolved.
fn output(
    c: &Checker,
    raw: RawOutput,
    resolve: &dyn Fn(PathBuf) -> PathBuf,
) -> Result<OutputConfig, ConfigError> {
    let dir = c.path(
        "output.dir",
        raw.dir.unwrap_or_else(|| PathBuf::from("out")),
    )?;
    Ok(OutputConfig {
        dir: resolve(dir),
        animation: raw.animation.unwrap_or(true),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::EMBEDDED_DEFAULT;

    fn parse(text: &str) -> Result<PipelineConfig, ConfigError> {
        PipelineConfig::from_toml_str(text, Path::new("pipeline.toml"), Path::new("/base"))
    }

    #[test]
    fn embedded_default_is_valid_and_points_at_fixtures() {
        let c = parse(EMBEDDED_DEFAULT).unwrap();
        let s = &c.surfaces[&c.input.surface];
        assert!((s.solid_fraction - 0.625).abs() < 1e-12);
        assert!((s.modulus_pa - 1.6e6).abs() < 1e-6);
        let m = c.input.manifest.expect("the default names a manifest");
        assert!(m.starts_with("/base/fixtures"), "{}", m.display());
        // The shipped file spells out the defaults; without its [detect]
        // table the same values come from DetectConfig::default().
        assert_eq!(c.detect, DetectConfig::default());
        let (head, tail) = EMBEDDED_DEFAULT
            .split_once("[detect]")
            .expect("a [detect] table");
        let rest = tail.find("\n[").map_or("", |i| &tail[i..]);
        let without = parse(&format!("{head}{rest}")).unwrap();
        assert_eq!(without.detect, DetectConfig::default());
    }

    #[test]
    fn unknown_key_is_rejected_with_its_name() {
        let e = parse("[camera]\nfsp = 10000\n").unwrap_err().to_string();
        assert!(e.contains("fsp"), "{e}");
        assert!(e.contains("pipeline.toml"), "{e}");
    }

    #[test]
    fn impossible_values_name_the_key_and_the_value() {
        let cases = [
            ("[sphere]\nradius_mm = -3\n", "sphere.radius_mm", "-3"),
            ("[camera]\nfps = 0\n", "camera.fps", "0"),
            (
                "[camera]\ndistortion_bound_px = -1\n",
                "camera.distortion_bound_px",
                "-1",
            ),
            (
                "[camera]\ndistortion_k1_per_px2 = 0.001\n",
                "camera.distortion_k1_per_px2",
                "0.001",
            ),
            (
                "[camera]\nedge_offset_px = 30\n",
                "camera.edge_offset_px",
                "30",
            ),
            (
                "[camera]\nedge_offset_px = -0.2\nedge_offset_spread_px = 0\n",
                "camera.edge_offset_spread_px",
                "0",
            ),
            (
                "[camera]\nedge_offset_spread_px = 0.1\n",
                "camera.edge_offset_spread_px",
                "0.1",
            ),
            (
                "[surface.p]\nmodulus_pa = 1e6\npillar_height_mm = 3\npillar_width_mm = 2\nchannel_width_mm = 1\nsolid_fraction = 1.5\n",
                "surface.p.solid_fraction",
                "1.5",
            ),
            ("[detect]\nbackground_frames = 0\n", "detect.background_frames", "0"),
            ("[detect]\nedge_half_window_px = 2\n", "detect.edge_half_window_px", "2"),
            ("[detect]\nedge_spacing_px = 0.5\n", "detect.edge_spacing_px", "0.5"),
        ];
        for (text, key, value) in cases {
            let e = parse(text).unwrap_err().to_string();
            assert!(e.contains(key) && e.contains(value), "{text} → {e}");
        }
    }

    #[test]
    fn several_surfaces_need_a_named_default() {
        let two = "[surface.a]\nmodulus_pa = 1e6\npillar_height_mm = 3\npillar_width_mm = 2\nchannel_width_mm = 1\n\
                   [surface.b]\nmodulus_pa = 2e6\npillar_height_mm = 3\npillar_width_mm = 2\nchannel_width_mm = 2\n";
        let e = parse(two).unwrap_err().to_string();
        assert!(e.contains("input.surface"), "{e}");
        let c = parse(&format!("[input]\nsurface = \"b\"\n{two}")).unwrap();
        assert_eq!(c.input.surface, "b");
        assert!((c.surfaces["b"].solid_fraction - 0.5).abs() < 1e-12);
        let e = parse(&format!("[input]\nsurface = \"zz\"\n{two}"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("\"zz\"") && e.contains("a, b"), "{e}");
    }
}
