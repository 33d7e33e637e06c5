//! Fuzz the configuration parser and validator (pipeline.toml): any text
//! gives a configuration or an error naming the key, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = dropscope::config::PipelineConfig::from_toml_str(
            text,
            std::path::Path::new("/c/pipeline.toml"),
            std::path::Path::new("/c"),
        );
    }
});
