//! Fuzz the run manifest parser: any bytes give runs or an error naming
//! the row, never a panic; every accepted run name is a valid file name.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(runs) = dropscope::dataset::manifest::parse_manifest(data, std::path::Path::new("/m/runs.csv"))
    {
        for r in runs {
            assert!(dropscope::dataset::run_name::check(&r.run).is_ok(), "{:?}", r.run);
        }
    }
});
