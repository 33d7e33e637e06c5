//! Coverage of the collapse fits' 95 % bootstrap intervals, by Monte Carlo:
//! N synthetic data sets obeying Eq. (8) (and pure power laws), each fitted,
//! counting how often the truth lies inside the interval.
//!
//!     cargo run --release --example collapse_coverage -- 200

use dropscope::collapse::fit::{fit_all, FitSettings};
use dropscope::collapse::groups::{compute, ContactRadius};
use dropscope::collapse::synthetic::{eq8_dataset, power_law_dataset, SyntheticSpec};
use dropscope::config::Surface;

fn main() {
    let n: u64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(100);
    let a = [1.26, -0.30, 0.05];
    let b = [3.53, -0.80, 0.20];
    let s = Surface::paper_pdms();
    let settings = FitSettings {
        resamples: 1000,
        seed: 1,
    };
    let mut hits = [0usize; 10];
    let mut width = [0.0f64; 10];
    // Coverage of value ± 1.96 stderr, for the series coefficients.
    let mut se_hits = [0usize; 6];
    for seed in 0..n {
        let recs = eq8_dataset(&SyntheticSpec::paper(30, 1000 + seed), a, b, [0.5, 1.6]);
        let groups: Vec<_> = recs
            .iter()
            .map(|r| compute(r, "pdms", &s, ContactRadius::Measured).unwrap())
            .collect();
        let fits = fit_all(&groups, settings);
        let ps = fits.psi_series.unwrap();
        let os = fits.omega_series.unwrap();
        for k in 0..3 {
            for (j, (est, t)) in [(&ps.coef[k], a[k]), (&os.coef[k], b[k])]
                .into_iter()
                .enumerate()
            {
                let ci = est.ci95.unwrap();
                let i = k + 3 * j;
                hits[i] += (ci[0] <= t && t <= ci[1]) as usize;
                width[i] += ci[1] - ci[0];
                let se = est.stderr.unwrap();
                se_hits[i] += ((est.value - t).abs() <= 1.96 * se) as usize;
            }
        }
        let mut spec = SyntheticSpec::paper(30, 5000 + seed);
        spec.rel_noise = [0.003, 0.01, 0.01, 0.01];
        let laws = [(3.0, 1.0 / 6.0, -2.0 / 3.0), (7.0, 1.0 / 3.0, -1.0 / 3.0)];
        let recs = power_law_dataset(&spec, &laws);
        let groups: Vec<_> = recs
            .iter()
            .map(|r| compute(r, "pdms", &s, ContactRadius::Measured).unwrap())
            .collect();
        let fits = fit_all(&groups, settings);
        for (e, (_, nu, mu)) in fits.exponents.iter().zip(laws) {
            let (lo, hi) = (e.nu_ci.unwrap(), e.mu_ci.unwrap());
            let i = if e.radius_mm < 5.0 { 6 } else { 8 };
            hits[i] += (lo[0] <= nu && nu <= lo[1]) as usize;
            hits[i + 1] += (hi[0] <= mu && mu <= hi[1]) as usize;
            width[i] += lo[1] - lo[0];
            width[i + 1] += hi[1] - hi[0];
        }
    }
    let names = [
        "A1", "A2", "A3", "B1", "B2", "B3", "nu(R=3)", "mu(R=3)", "nu(R=7)", "mu(R=7)",
    ];
    println!("{n} data sets; 95 % bootstrap interval coverage and mean width:");
    for i in 0..10 {
        let se = if i < 6 {
            format!(
                "  (±1.96 stderr: {:5.1} %)",
                100.0 * se_hits[i] as f64 / n as f64
            )
        } else {
            String::new()
        };
        println!(
            "{:>8}: {:5.1} %  width {:.4}{se}",
            names[i],
            100.0 * hits[i] as f64 / n as f64,
            width[i] / n as f64
        );
    }
}
