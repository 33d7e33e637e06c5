//! The integration tests, compiled into one binary (one module per stage).

mod accuracy_effects;
mod cli;
mod collapse;
mod detect;
mod hostile;
mod parallel;
mod pcc_xml;
mod process;
mod process_formats;
mod process_job;
mod render;
mod render_contact;
mod render_real;
mod render_saturated;
mod report;
mod run;
mod setup_infer;
mod shards;
mod slurm;
mod source;
mod source_colour;
mod source_inputs;
mod source_photron;
mod source_tiff;
mod timings;
mod wide_frames;

/// `../shared/data/phantom-samples/` beside the checkout, with `rel` joined:
/// the real Phantom files some tests read. Without that folder, the test
/// stops saying where it looked and what to do, not with a bare "file not
/// found".
pub fn phantom_sample(rel: &str) -> std::path::PathBuf {
    let root =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/phantom-samples");
    assert!(
        root.is_dir(),
        "the real Phantom sample files are missing: looked for {}. These tests need the \
         project's shared/ folder beside the checkout (shared/data/phantom-samples/); \
         clone or copy it there, or run the tests from a checkout that sits beside it",
        root.display()
    );
    root.join(rel)
}

/// `../shared/data/real-footage/` beside the checkout, with `rel` joined:
/// real recordings of falling balls and drops (each folder's SOURCE.md
/// gives its origin and known values). Missing, the test stops saying where
/// it looked, as [`phantom_sample`] does.
pub fn real_footage(rel: &str) -> std::path::PathBuf {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/real-footage");
    assert!(
        root.is_dir(),
        "the real footage files are missing: looked for {}. These tests need the \
         project's shared/ folder beside the checkout (shared/data/real-footage/)",
        root.display()
    );
    root.join(rel)
}
