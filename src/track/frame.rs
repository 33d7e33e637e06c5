//! What the tracker found in one frame ([`FrameTrack`]), and how a
//! frame's record is stored in a run's spool of records
//! ([`crate::util::records`]): as the bits of its fields, so that what is read
//! back is the same value.

use crate::detect::{CircleFit, Covariance};
use crate::util::records::{Put, Record, Take};

/// What the tracker found in one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameTrack {
    /// Index in the source.
    pub index: usize,
    /// Camera image number.
    pub frame: i64,
    /// Time of the frame, s after the trigger.
    pub t_s: f64,
    /// Pass 1: radius free.
    pub free: Option<CircleFit>,
    /// Pass 2: radius held at the calibrated R_px.
    pub held: Option<CircleFit>,
    /// `recovered`, `partial` (the circle leaves the frame), `missing`,
    /// `outlier` (off its neighbours in flight: [`super::outliers`]), `excluded`
    /// (by a person).
    pub flags: FrameFlags,
}

/// One of a frame's [`FrameFlags`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flag {
    /// Found again by a search after frames without a fit.
    Recovered,
    /// The circle leaves the frame.
    Partial,
    /// Looked for and not found (or its held fit failed).
    Missing,
    /// In free flight, off the path of the frames around it far beyond
    /// the errors ([`super::outliers`]): mismeasured. The measurement leaves it
    /// out of its fits.
    Outlier,
    /// Left out of every fit by a person (`dropscope review`): its fits
    /// are kept and shown, never used.
    Excluded,
}

impl Flag {
    const ALL: [Flag; 5] = [
        Flag::Recovered,
        Flag::Partial,
        Flag::Missing,
        Flag::Outlier,
        Flag::Excluded,
    ];

    /// The flag's word in the track CSV.
    pub fn name(self) -> &'static str {
        match self {
            Flag::Recovered => "recovered",
            Flag::Partial => "partial",
            Flag::Missing => "missing",
            Flag::Outlier => "outlier",
            Flag::Excluded => "excluded",
        }
    }
}

/// A frame's flags: one byte a frame, not a list (a long movie's track
/// holds a record a frame).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FrameFlags(u8);

impl FrameFlags {
    /// Set flag `f`.
    pub fn insert(&mut self, f: Flag) {
        self.0 |= 1 << f as u8;
    }

    /// Whether flag `f` is set.
    pub fn contains(self, f: Flag) -> bool {
        self.0 & (1 << f as u8) != 0
    }

    /// The flags as one byte (a bit per [`Flag`]), as stored in a file.
    pub fn bits(self) -> u8 {
        self.0
    }

    /// The flags stored as one byte by [`FrameFlags::bits`].
    pub fn from_bits(bits: u8) -> Self {
        FrameFlags(bits)
    }

    /// The flags' words, space-separated, in [`Flag`]'s order (the order
    /// the tracker sets them in); empty without flags.
    pub fn text(self) -> String {
        let words: Vec<&str> = Flag::ALL
            .into_iter()
            .filter(|&f| self.contains(f))
            .map(Flag::name)
            .collect();
        words.join(" ")
    }
}

/// A circle fit: a tag (0 none, 1 full covariance, 2 centre only), then
/// its fields, a centre-only covariance padded to six numbers.
const FIT_BYTES: usize = 1 + 8 * 3 + 8 * 6 + 8 + 4 * 3 + 8;

fn put_fit(p: &mut Put, fit: &Option<CircleFit>) {
    let Some(f) = fit else {
        p.0.resize(p.0.len() + FIT_BYTES, 0);
        return;
    };
    let cov: [f64; 6] = match f.cov {
        Covariance::Full(c) => {
            p.u8(1);
            c
        }
        Covariance::CentreOnly([a, b, c]) => {
            p.u8(2);
            [a, b, c, 0.0, 0.0, 0.0]
        }
    };
    for v in [f.x_px, f.z_px, f.r_px].into_iter().chain(cov) {
        p.f64(v);
    }
    p.f64(f.residual_px);
    for v in [f.n_used, f.inliers, f.iterations] {
        p.u32(v);
    }
    p.f64(f.scale_px);
}

fn take_fit(t: &mut Take) -> Option<CircleFit> {
    let tag = t.u8();
    if tag == 0 {
        t.0 = &t.0[FIT_BYTES - 1..];
        return None;
    }
    let (x_px, z_px, r_px) = (t.f64(), t.f64(), t.f64());
    let c: [f64; 6] = std::array::from_fn(|_| t.f64());
    let cov = if tag == 1 {
        Covariance::Full(c)
    } else {
        Covariance::CentreOnly([c[0], c[1], c[2]])
    };
    Some(CircleFit {
        x_px,
        z_px,
        r_px,
        cov,
        residual_px: t.f64(),
        n_used: t.u32(),
        inliers: t.u32(),
        iterations: t.u32(),
        scale_px: t.f64(),
    })
}

impl Record for FrameTrack {
    const BYTES: usize = 8 * 3 + 1 + 2 * FIT_BYTES;

    fn put(&self, out: &mut Vec<u8>) {
        let mut p = Put(out);
        p.u64(self.index as u64);
        p.u64(self.frame as u64);
        p.f64(self.t_s);
        p.u8(self.flags.bits());
        put_fit(&mut p, &self.free);
        put_fit(&mut p, &self.held);
    }

    fn get(b: &[u8]) -> Self {
        let mut t = Take(b);
        FrameTrack {
            index: t.u64() as usize,
            frame: t.u64() as i64,
            t_s: t.f64(),
            flags: FrameFlags::from_bits(t.u8()),
            free: take_fit(&mut t),
            held: take_fit(&mut t),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::util::records::{Records, BLOCK};

    fn fit(i: usize, full: bool) -> CircleFit {
        let v = |k: usize| (i * 7 + k) as f64 / 3.0 - 5.0;
        CircleFit {
            x_px: v(1),
            z_px: -0.0,
            r_px: v(2),
            cov: if full {
                Covariance::Full([v(3), v(4), v(5), v(6), v(7), f64::MIN_POSITIVE])
            } else {
                Covariance::CentreOnly([v(3), -v(4), 1e-300])
            },
            residual_px: v(8),
            n_used: i as u32,
            inliers: u32::MAX - i as u32,
            iterations: 3,
            scale_px: v(9),
        }
    }

    /// Frames with no fit, a free fit only, both, and flags.
    fn frame(i: usize) -> FrameTrack {
        let mut flags = FrameFlags::default();
        if i.is_multiple_of(3) {
            flags.insert(Flag::Missing);
        }
        if i.is_multiple_of(5) {
            flags.insert(Flag::Partial);
        }
        FrameTrack {
            index: i,
            frame: i as i64 - 1000,
            t_s: (i as f64 - 1000.0) / 60_000.0,
            free: (!i.is_multiple_of(4)).then(|| fit(i, true)),
            held: (i % 4 > 1).then(|| fit(i, false)),
            flags,
        }
    }

    #[test]
    fn records_in_a_file_read_back_as_the_same_bits_as_in_memory() {
        let n = 2 * BLOCK + 123;
        let (mut mem, mut file) = (Records::new(n), Records::new(100));
        for i in 0..n {
            mem.push(frame(i)).unwrap();
            file.push(frame(i)).unwrap();
        }
        mem.flush().unwrap();
        file.flush().unwrap();
        assert!(!mem.spilled() && file.spilled());
        assert_eq!((mem.len(), file.len()), (n, n));
        // Debug prints each f64's shortest round-trip form: equal text is
        // equal bits.
        assert_eq!(format!("{mem:?}"), format!("{file:?}"));
        let expected: Vec<FrameTrack> = (0..n).map(frame).collect();
        assert_eq!(format!("{file:?}"), format!("{expected:?}"));
        // One record, replaced, and every record updated block by block.
        for r in [&mut mem, &mut file] {
            assert_eq!(
                format!("{:?}", r.get(BLOCK + 7).unwrap()),
                format!("{:?}", frame(BLOCK + 7))
            );
            r.set(BLOCK + 7, frame(1)).unwrap();
            let mut seen = Vec::new();
            r.update(|lo, block| -> std::io::Result<()> {
                seen.push((lo, block.len()));
                for f in block {
                    f.index += 1;
                }
                Ok(())
            })
            .unwrap();
            assert_eq!(seen.iter().map(|s| s.1).sum::<usize>(), n);
            r.check().unwrap();
        }
        assert_eq!(format!("{mem:?}"), format!("{file:?}"));
        let got: Vec<usize> = file.iter().map(|f| f.index).collect();
        let want: Vec<usize> = (0..n)
            .map(|i| if i == BLOCK + 7 { 2 } else { i + 1 })
            .collect();
        assert_eq!(got, want);
    }
}
