//! Write a synthetic drops.csv (and a few tracks) obeying Eq. (8) of
//! Maruoka 2019 with known coefficients, to try `dropscope collapse` on:
//!
//!     cargo run --release --example synthetic_drops -- /tmp/syn
//!     cargo run --release -- collapse /tmp/syn/drops.csv --out /tmp/syn/out

use dropscope::collapse::synthetic::{contact_track, eq8_dataset, SyntheticSpec};
use std::path::PathBuf;

fn main() -> anyhow::Result<()> {
    let dir = PathBuf::from(
        std::env::args()
            .nth(1)
            .unwrap_or_else(|| "synthetic".into()),
    );
    std::fs::create_dir_all(dir.join("tracks"))?;
    let spec = SyntheticSpec::paper(30, 1);
    // A1 = 2^(1/3) and B1 = C0 (the energy balance); crossover A1/A2 = 1.4.
    let mut recs = eq8_dataset(&spec, [1.26, 0.9, -0.15], [3.53, 1.5, -0.3], [0.5, 1.5]);
    // Tracks for the first drop of each radius, from the contact ODE; their
    // event times go into the records.
    for rec in recs
        .iter_mut()
        .filter(|r| r.run.ends_with("_00") || r.run.ends_with("_29"))
    {
        let v = rec.v_impact_m_s.unwrap_or(1.0);
        let (rows, t_in, t_out) = contact_track(
            rec.sphere_radius_mm,
            7800.0,
            v,
            &spec.surface,
            10_000.0,
            0.05,
        );
        rec.t_contact_s = Some(t_in);
        rec.t_rebound_s = Some(t_out);
        let mut w = csv::Writer::from_path(dir.join("tracks").join(format!("{}.csv", rec.run)))?;
        for r in rows {
            w.serialize(r)?;
        }
        w.flush()?;
    }
    dropscope::dataset::write_csv(&dir.join("drops.csv"), &recs)?;
    println!(
        "{} drops in {}",
        recs.len(),
        dir.join("drops.csv").display()
    );
    Ok(())
}
