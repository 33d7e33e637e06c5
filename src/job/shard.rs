//! One job split over many processes: `dropscope run --shard K/N`
//! takes the K-th of N shares of the configured runs.
//!
//! The shares are balanced by frame count and depend only on the run list
//! and the inputs, so N processes started anywhere (the tasks of a Slurm
//! array) agree on them without talking to each other. Each shard commits
//! its runs into the shared output folder like the whole job does (files,
//! then the cache entry); the whole job run afterwards finds them all in the
//! cache and only assembles drops.csv, the collapse and the report.

use crate::dataset::manifest::RunSpec;
use crate::source::frame_decode::ImageKind;
use std::path::Path;

/// Frames a run is counted for on top of its frames: its fixed cost
/// (background, surface line, fits, figures) weighs about as much as 100
/// frames of a rendered drop (docs/performance.md, the `track` bench's
/// fixed cost a run against its cost a frame).
pub const FIXED_COST_FRAMES: u64 = 100;

/// The K-th (`index`, from 0) of `count` shares.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// Which share, K, from 0.
    pub index: usize,
    /// How many shares, N (at least 1).
    pub count: usize,
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// Why `--shard` could not be understood.
#[derive(Debug, thiserror::Error)]
pub enum ShardError {
    /// `--shard` is neither `K/N` with 0 ≤ K < N nor `slurm` (the text given).
    #[error(
        "--shard {0}: expected K/N with 0 <= K < N (e.g. 2/8), or `slurm` inside a Slurm array job"
    )]
    Syntax(String),
    /// `--shard slurm` outside a Slurm array job (the variable not set).
    #[error(
        "--shard slurm: {0} is not set: this is not a task of a Slurm array job. Submit with \
         `sbatch --array=0-<N-1>` (`dropscope slurm` writes the script), or give --shard K/N"
    )]
    NotArray(&'static str),
    /// A Slurm array variable does not hold a whole number.
    #[error("--shard slurm: {name}={value} is not a whole number")]
    BadVariable {
        /// The variable's name.
        name: &'static str,
        /// Its value.
        value: String,
    },
}

impl Shard {
    /// `K/N`, or `slurm`: K = `SLURM_ARRAY_TASK_ID` − `SLURM_ARRAY_TASK_MIN`,
    /// N = `SLURM_ARRAY_TASK_COUNT`, read through `env`.
    pub fn parse(spec: &str, env: &dyn Fn(&str) -> Option<String>) -> Result<Shard, ShardError> {
        let (index, count) = if spec == "slurm" {
            let var = |name: &'static str| -> Result<usize, ShardError> {
                let value = env(name).ok_or(ShardError::NotArray(name))?;
                value
                    .trim()
                    .parse()
                    .map_err(|_| ShardError::BadVariable { name, value })
            };
            let id = var("SLURM_ARRAY_TASK_ID")?;
            let min = var("SLURM_ARRAY_TASK_MIN")?;
            let count = var("SLURM_ARRAY_TASK_COUNT")?;
            (id.checked_sub(min), Some(count))
        } else {
            let (k, n) = spec
                .split_once('/')
                .ok_or_else(|| ShardError::Syntax(spec.into()))?;
            (k.trim().parse().ok(), n.trim().parse().ok())
        };
        match (index, count) {
            (Some(index), Some(count)) if index < count => Ok(Shard { index, count }),
            _ => Err(ShardError::Syntax(spec.into())),
        }
    }
}

/// Worker threads a Slurm task was given (`SLURM_CPUS_PER_TASK`), if any.
pub fn slurm_cpus_per_task(env: &dyn Fn(&str) -> Option<String>) -> Option<usize> {
    env("SLURM_CPUS_PER_TASK")?
        .trim()
        .parse()
        .ok()
        .filter(|&n| n > 0)
}

/// Frames of an input without decoding any: a folder's image files, a
/// `.cine`'s image count from its header; 0 when it cannot be read (the
/// run will fail quickly).
pub fn frame_count(path: &Path) -> u64 {
    if path.is_dir() {
        return std::fs::read_dir(path).map_or(0, |entries| {
            entries
                .flatten()
                .filter(|e| {
                    e.path()
                        .extension()
                        .and_then(|x| x.to_str())
                        .is_some_and(|x| ImageKind::from_extension(x).is_some())
                })
                .count() as u64
        });
    }
    let options = crate::source::OpenOptions {
        // The count does not depend on it; a cine carries its own.
        fps_fallback: Some(1.0),
        ..Default::default()
    };
    crate::source::open(path, &options).map_or(0, |s| s.meta().frame_count as u64)
}

/// The shard of each of the runs weighing `weights`, `count` shards:
/// heaviest run first to the lightest shard so far (ties: the earlier run,
/// the lower shard), which keeps every shard within one run of the mean.
pub fn assign(weights: &[u64], count: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..weights.len()).collect();
    order.sort_by_key(|&i| (std::cmp::Reverse(weights[i]), i));
    let mut load = vec![0u64; count.max(1)];
    let mut shard_of = vec![0; weights.len()];
    for i in order {
        let (k, _) = load
            .iter()
            .enumerate()
            .min_by_key(|&(k, l)| (*l, k))
            .unwrap_or((0, &0));
        load[k] += weights[i];
        shard_of[i] = k;
    }
    shard_of
}

/// The runs of `shard`, in their configured order.
///
/// The runs of one camera set-up (the manifest's `setup` column) stay in one
/// share: their scale is pooled from all of them. With `infer_setups`, the
/// runs without a `setup` are one share too: which of them share a set-up
/// is found from all of their images (so every shard count gives the same
/// numbers).
pub fn select(runs: &[RunSpec], shard: Shard, infer_setups: bool) -> Vec<RunSpec> {
    let mut groups = crate::pipeline::setups(runs);
    let open = |g: &Vec<usize>| runs[g[0]].setup.is_none();
    if infer_setups && groups.iter().filter(|g| open(g)).count() >= 2 {
        let joined: Vec<usize> = groups
            .iter()
            .filter(|g| open(g))
            .flatten()
            .copied()
            .collect();
        groups.retain(|g| !open(g));
        groups.push(joined);
    }
    let weights: Vec<u64> = groups
        .iter()
        .map(|g| {
            g.iter()
                .map(|&i| frame_count(&runs[i].path) + FIXED_COST_FRAMES)
                .sum()
        })
        .collect();
    let shard_of = assign(&weights, shard.count);
    let mut keep: Vec<usize> = groups
        .iter()
        .zip(shard_of)
        .filter(|(_, k)| *k == shard.index)
        .flat_map(|(g, _)| g.iter().copied())
        .collect();
    keep.sort_unstable();
    keep.into_iter().map(|i| runs[i].clone()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env<'a>(vars: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |k| {
            vars.iter()
                .find(|(n, _)| *n == k)
                .map(|(_, v)| v.to_string())
        }
    }

    #[test]
    fn shard_specs_and_slurm_variables() {
        let none = env(&[]);
        assert_eq!(
            Shard::parse("2/8", &none).unwrap(),
            Shard { index: 2, count: 8 }
        );
        for bad in ["8/8", "-1/3", "1", "a/b", "1/0", "0/"] {
            let e = Shard::parse(bad, &none).unwrap_err().to_string();
            assert!(
                e.contains(&format!("--shard {bad}:")) && e.contains("K/N"),
                "{e}"
            );
        }
        let e = Shard::parse("slurm", &none).unwrap_err().to_string();
        assert!(
            e.contains("SLURM_ARRAY_TASK_ID is not set") && e.contains("sbatch --array"),
            "{e}"
        );
        // An array 5-7: task 6 is the second of three.
        let vars = [
            ("SLURM_ARRAY_TASK_ID", "6"),
            ("SLURM_ARRAY_TASK_MIN", "5"),
            ("SLURM_ARRAY_TASK_COUNT", "3"),
            ("SLURM_CPUS_PER_TASK", "4"),
        ];
        let e6 = env(&vars);
        assert_eq!(
            Shard::parse("slurm", &e6).unwrap(),
            Shard { index: 1, count: 3 }
        );
        assert_eq!(slurm_cpus_per_task(&e6), Some(4));
        assert_eq!(slurm_cpus_per_task(&none), None);
        let bad = [
            ("SLURM_ARRAY_TASK_ID", "x"),
            ("SLURM_ARRAY_TASK_MIN", "0"),
            ("SLURM_ARRAY_TASK_COUNT", "3"),
        ];
        let e = Shard::parse("slurm", &env(&bad)).unwrap_err().to_string();
        assert!(e.contains("SLURM_ARRAY_TASK_ID=x"), "{e}");
    }

    #[test]
    fn shares_cover_every_run_once_and_balance_frames() {
        // Runs of 90 to 6 000 frames, in a fixed pseudo-random order.
        let weights: Vec<u64> = (0..37u64).map(|i| 90 + (i * 7919) % 61 * 97).collect();
        let total: u64 = weights.iter().sum();
        let max = *weights.iter().max().unwrap();
        for count in [1, 2, 3, 4, 7, 50] {
            let shard_of = assign(&weights, count);
            assert_eq!(shard_of, assign(&weights, count), "not deterministic");
            let mut load = vec![0u64; count];
            for (w, k) in weights.iter().zip(&shard_of) {
                assert!(*k < count);
                load[*k] += w;
            }
            let mean = total / count as u64;
            for l in &load {
                // Greedy heaviest-first: no share exceeds the mean by a run.
                assert!(*l <= mean + max, "{count} shards: {load:?}");
            }
            if count <= 4 {
                let (lo, hi) = (load.iter().min().unwrap(), load.iter().max().unwrap());
                assert!(hi - lo <= max, "{count} shards: {load:?}");
            }
        }
    }

    /// Runs without a `setup` stay in one share when set-ups are inferred
    /// (which of them share one depends on all of them), and spread over
    /// the shares when not; a named set-up stays whole either way.
    #[test]
    fn runs_without_a_setup_stay_together_when_setups_are_inferred() {
        let run = crate::test_support::run_spec;
        let runs = vec![
            run("a", None),
            run("b", Some("cam")),
            run("c", None),
            run("d", Some("cam")),
            run("e", None),
            run("f", None),
        ];
        let names = |k: usize, infer: bool| -> Vec<String> {
            select(&runs, Shard { index: k, count: 2 }, infer)
                .into_iter()
                .map(|r| r.run)
                .collect()
        };
        let (s0, s1) = (names(0, true), names(1, true));
        let open = ["a", "c", "e", "f"].map(String::from).to_vec();
        let named = ["b", "d"].map(String::from).to_vec();
        assert!(
            (s0 == open && s1 == named) || (s1 == open && s0 == named),
            "{s0:?} {s1:?}"
        );
        let (s0, s1) = (names(0, false), names(1, false));
        assert_eq!(s0.len() + s1.len(), 6);
        assert!(s0.len() >= 2 && s1.len() >= 2, "{s0:?} {s1:?}");
    }

    #[test]
    fn frames_are_counted_without_decoding() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path().join("run");
        std::fs::create_dir(&d).unwrap();
        for i in 0..12 {
            std::fs::write(d.join(format!("r_{i:03}.tif")), b"not even a tiff").unwrap();
        }
        std::fs::write(d.join("r.xml"), b"<chd/>").unwrap();
        assert_eq!(frame_count(&d), 12);
        assert_eq!(frame_count(&dir.path().join("missing")), 0);
        // A real cine: 97 frames (phantom-samples README), when the
        // project's shared/ folder is beside the checkout.
        let cine = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../shared/data/phantom-samples/pims/cine_legacy.cine");
        if !cine.is_file() && std::env::var("DROPSCOPE_REQUIRE_ALL").as_deref() != Ok("1") {
            use std::io::Write;
            let _ = writeln!(
                std::io::stderr(),
                "SKIPPED: shard::tests::frames_are_counted_without_decoding, its real cine: {} \
                 is missing: the project's shared/ folder must sit beside the checkout (set \
                 DROPSCOPE_REQUIRE_ALL=1 to fail instead)",
                cine.display()
            );
            return;
        }
        assert_eq!(frame_count(&cine), 97);
    }
}
