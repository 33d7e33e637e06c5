//! A resolved [`PipelineConfig`] printed back as `pipeline.toml` text, with
//! the key names a user writes (`radius_mm`, `[surface.<name>]`), not the
//! SI names dropscope uses inside (`radius_m`, `surfaces`): what
//! `dropscope check-config` prints, ready to be saved and edited.

use super::settings::PipelineConfig;
use toml::Value;

/// A length in metres as millimetres, to 10 significant digits (so that
/// 3.5 mm stored as 0.0035 m prints as 3.5, not 3.5000000000000004).
fn to_mm(m: f64) -> f64 {
    format!("{:.9e}", m * 1e3).parse().unwrap_or(m * 1e3)
}

/// Rename every `<x>_m` key to `<x>_mm` (value in mm), recursively.
fn to_file_units(v: Value) -> Value {
    match v {
        Value::Table(t) => Value::Table(
            t.into_iter()
                .map(|(k, v)| match (k.strip_suffix("_m"), &v) {
                    (Some(stem), Value::Float(m)) => {
                        (format!("{stem}_mm"), Value::Float(to_mm(*m)))
                    }
                    _ => (k, to_file_units(v)),
                })
                .collect(),
        ),
        Value::Array(a) => Value::Array(a.into_iter().map(to_file_units).collect()),
        other => other,
    }
}

impl PipelineConfig {
    /// The configuration with the keys of `pipeline.toml` (paths as
    /// resolved): what [`Self::to_toml`] prints and `provenance.json`
    /// records.
    pub fn to_file_value(&self) -> Value {
        let Ok(Value::Table(mut t)) = Value::try_from(self) else {
            return Value::Table(Default::default());
        };
        // The command line's values are no key of the file.
        t.remove("command_line");
        if let Some(s) = t.remove("surfaces") {
            t.insert("surface".into(), s);
        }
        to_file_units(Value::Table(t))
    }

    /// The configuration as `pipeline.toml` text (paths as resolved).
    pub fn to_toml(&self) -> String {
        toml::to_string(&self.to_file_value()).unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use crate::config::{PipelineConfig, EMBEDDED_DEFAULT};
    use std::path::Path;

    /// check-config prints TOML with the file's keys, not a Rust debug
    /// dump whose names (`radius_m`, `surfaces`) are not the file's keys.
    #[test]
    fn the_printed_toml_reads_back_as_the_same_configuration() {
        let text = EMBEDDED_DEFAULT.replace("# radius_mm = 4.5", "radius_mm = 4.5");
        let cfg = PipelineConfig::from_toml_str(&text, Path::new("p.toml"), Path::new("")).unwrap();
        let printed = cfg.to_toml();
        assert!(printed.contains("radius_mm = 4.5"), "{printed}");
        assert!(printed.contains("[surface.pdms]"), "{printed}");
        assert!(printed.contains("pillar_height_mm = 3.5\n"), "{printed}");
        assert!(
            !printed.contains("_m ") && !printed.contains("surfaces"),
            "{printed}"
        );
        let back = PipelineConfig::from_toml_str(&printed, Path::new("x"), Path::new("")).unwrap();
        assert_eq!(back, cfg);
    }
}
