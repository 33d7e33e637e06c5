//! Tests of [`crate::job::batch`].

use super::*;

/// provenance.json's configuration has pipeline.toml's keys
/// (`radius_mm`, `surface.<name>`; it had the SI names `radius_m`,
/// `surfaces`), and read back as TOML it is the same configuration.
#[test]
fn provenance_records_the_configuration_with_the_files_keys() {
    let text = crate::config::EMBEDDED_DEFAULT.replace("# radius_mm = 4.5", "radius_mm = 4.5");
    let cfg = PipelineConfig::from_toml_str(&text, Path::new("p.toml"), Path::new("")).unwrap();
    let doc: serde_json::Value =
        serde_json::from_slice(&provenance_json(&cfg, "p.toml", &[], &Review::default())).unwrap();
    let c = &doc["configuration"];
    assert_eq!(c["sphere"]["radius_mm"], serde_json::json!(4.5), "{c}");
    assert_eq!(
        c["surface"]["pdms"]["pillar_height_mm"],
        serde_json::json!(3.5)
    );
    assert!(c.get("surfaces").is_none() && c["sphere"].get("radius_m").is_none());
    let as_toml = toml::to_string(&c).unwrap();
    let back = PipelineConfig::from_toml_str(&as_toml, Path::new("x"), Path::new("")).unwrap();
    assert_eq!(back, cfg);
}

#[test]
fn runs_are_found_at_any_depth_in_name_order() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (folder, file) in [
        ("2019-06-14/R3mm_01", "R3mm_01_000000.tif"),
        ("2019-06-14/R3mm_02", "R3mm_02.xml"),
        ("2019-06-15/notes", "readme.txt"),
        ("2019-06-15/cines", "b.cine"),
        ("2019-06-15/cines", "a.CINE"),
        ("2019-06-15/cines/R5/R5_01", "x_1.png"),
    ] {
        std::fs::create_dir_all(d.join(folder)).unwrap();
        std::fs::write(d.join(folder).join(file), b"").unwrap();
    }
    let found = discover_runs(&[d.to_path_buf()]).unwrap();
    let rel: Vec<String> = found
        .iter()
        .map(|p| p.strip_prefix(d).unwrap().display().to_string())
        .collect();
    assert_eq!(
        rel,
        [
            "2019-06-14/R3mm_01",
            "2019-06-14/R3mm_02",
            "2019-06-15/cines/R5/R5_01",
            "2019-06-15/cines/a.CINE",
            "2019-06-15/cines/b.cine",
        ]
    );
    let e = discover_runs(&[d.join("2019-06-15/notes")])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("no run folder or .cine") && e.contains("notes"),
        "{e}"
    );
}
