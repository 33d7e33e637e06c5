//! A movie's per-frame index — camera image numbers, times, exposures — in
//! memory that does not grow with the movie's length: the
//! numbers as runs of consecutive ones (O(gaps)), a `.cine`'s times and
//! exposures read from the file itself a block at a time when asked for.
//! Lookups give exactly the values a table would hold.

use std::cell::RefCell;
use std::fs::File;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use super::SourceError;

/// The camera image number of every readable frame, as runs of consecutive
/// numbers: `(first index, its number)` per run. A movie without gaps is
/// one run, whatever its length.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct FrameNumbers {
    len: usize,
    runs: Arc<[(usize, i64)]>,
}

impl FrameNumbers {
    /// `first, first + 1, …`: `len` numbers.
    pub fn consecutive(first: i64, len: usize) -> Self {
        FrameNumbers {
            len,
            runs: if len == 0 {
                Arc::new([])
            } else {
                Arc::new([(0, first)])
            },
        }
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.len
    }

    /// No frame at all.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The number of frame `index`, `None` past the end.
    pub fn get(&self, index: usize) -> Option<i64> {
        if index >= self.len {
            return None;
        }
        let run = self.runs.partition_point(|r| r.0 <= index) - 1;
        let (start, number) = self.runs[run];
        Some(number + (index - start) as i64)
    }

    /// The first frame's image number; `None` when empty.
    pub fn first(&self) -> Option<i64> {
        self.get(0)
    }

    /// The last frame's image number; `None` when empty.
    pub fn last(&self) -> Option<i64> {
        self.len.checked_sub(1).and_then(|i| self.get(i))
    }

    /// Every number in index order.
    pub fn iter(&self) -> impl DoubleEndedIterator<Item = i64> + ExactSizeIterator + '_ {
        (0..self.len).map(|i| self.get(i).unwrap_or_default())
    }

    /// Bytes held on the heap (the runs).
    pub fn heap_bytes(&self) -> usize {
        std::mem::size_of_val(&*self.runs)
    }
}

impl FromIterator<i64> for FrameNumbers {
    /// Any sequence, in order: a new run starts wherever a number is not
    /// its predecessor's plus one.
    fn from_iter<I: IntoIterator<Item = i64>>(numbers: I) -> Self {
        let mut runs: Vec<(usize, i64)> = Vec::new();
        let mut len = 0;
        let mut prev: Option<i64> = None;
        for n in numbers {
            if prev.and_then(|p| p.checked_add(1)) != Some(n) {
                runs.push((len, n));
            }
            prev = Some(n);
            len += 1;
        }
        FrameNumbers {
            len,
            runs: runs.into(),
        }
    }
}

/// Seconds per frame (times, exposures): a table in memory, or the values
/// as a `.cine` stores them, read from the file when asked for.
#[derive(Debug, Clone, PartialEq)]
pub enum FrameValues {
    /// The values in memory, one per frame.
    Memory(Arc<[f64]>),
    /// The values as the file stores them, read when asked for.
    File(Arc<ValuesInFile>),
}

impl From<Vec<f64>> for FrameValues {
    fn from(v: Vec<f64>) -> Self {
        FrameValues::Memory(v.into())
    }
}

/// TIME64: seconds since 1970-01-01 UTC in 32.32 fixed point (phantom.md §10).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Time64 {
    /// The fraction of a second, in units of 2⁻³² s.
    pub fractions: u32,
    /// Whole seconds since 1970-01-01 00:00 UTC.
    pub seconds: u32,
}

impl Time64 {
    /// `seconds<<32 | fractions` with the two flag bits of `fractions` cleared.
    pub fn ticks(self) -> i128 {
        (i128::from(self.seconds) << 32) | i128::from(self.fractions & !3)
    }
    /// `self − other` in seconds.
    pub fn seconds_since(self, other: Time64) -> f64 {
        (self.ticks() - other.ticks()) as f64 / 4_294_967_296.0
    }
}

/// How a value is stored in the file (formats/phantom.md §10).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stored {
    /// A TIME64 (8 bytes, tag 1002), given as seconds since this one (the
    /// trigger time).
    Time64Since(Time64),
    /// A u32 in units of 2⁻³² s (4 bytes, tag 1003 exposures).
    Fraction32,
}

impl Stored {
    fn bytes(self) -> usize {
        match self {
            Stored::Time64Since(_) => 8,
            Stored::Fraction32 => 4,
        }
    }
    fn what(self) -> &'static str {
        match self {
            Stored::Time64Since(_) => "time stamp (tag 1002)",
            Stored::Fraction32 => "exposure (tag 1003)",
        }
    }
    fn decode(self, b: &[u8]) -> f64 {
        match self {
            Stored::Time64Since(trigger) => Time64 {
                fractions: u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
                seconds: u32::from_le_bytes([b[4], b[5], b[6], b[7]]),
            }
            .seconds_since(trigger),
            Stored::Fraction32 => {
                f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])) / 4_294_967_296.0
            }
        }
    }
}

/// `len` values stored from byte `start` of a file.
#[derive(Debug)]
pub struct ValuesInFile {
    /// Names this table in the threads' caches (never reused).
    id: u64,
    file: File,
    path: PathBuf,
    start: u64,
    len: usize,
    stored: Stored,
}

impl PartialEq for ValuesInFile {
    fn eq(&self, o: &Self) -> bool {
        (&self.path, self.start, self.len, self.stored) == (&o.path, o.start, o.len, o.stored)
    }
}

impl ValuesInFile {
    /// `len` values stored as `stored` from byte `start` of `file` (named `path` in messages).
    pub fn new(file: File, path: PathBuf, start: u64, len: usize, stored: Stored) -> Self {
        static NEXT_ID: AtomicU64 = AtomicU64::new(0);
        ValuesInFile {
            id: NEXT_ID.fetch_add(1, Ordering::Relaxed),
            file,
            path,
            start,
            len,
            stored,
        }
    }

    /// Values `lo..hi` decoded into `out`; an error names frame `asked`.
    fn read(
        &self,
        lo: usize,
        hi: usize,
        asked: usize,
        out: &mut Vec<f64>,
    ) -> Result<(), SourceError> {
        let width = self.stored.bytes();
        let at = self.start + (lo * width) as u64;
        let mut bytes = vec![0u8; (hi - lo) * width];
        crate::util::io::read_at(&self.file, at, &mut bytes).map_err(|e| SourceError::Frame {
            path: self.path.clone(),
            index: asked,
            reason: format!(
                "reading its {} (frames {lo}..{hi} at byte {at}): {e}",
                self.stored.what()
            ),
        })?;
        out.clear();
        out.extend(bytes.chunks_exact(width).map(|b| self.stored.decode(b)));
        Ok(())
    }
}

/// Values read from a file at once, and kept per thread.
const BLOCK: usize = 4096;
/// Blocks each thread keeps (a walk over two places of one table at once
/// reads each block once).
const BLOCKS_KEPT: usize = 4;

/// A block of a table's values kept by a thread.
struct Kept {
    table: u64,
    block: usize,
    /// When it was last used (the thread's count of lookups).
    used: u64,
    values: Vec<f64>,
}

thread_local! {
    /// At most [`BLOCKS_KEPT`] blocks, and the count of lookups.
    static KEPT: RefCell<(Vec<Kept>, u64)> = const { RefCell::new((Vec::new(), 0)) };
}

impl FrameValues {
    /// Number of values (frames).
    pub fn len(&self) -> usize {
        match self {
            FrameValues::Memory(v) => v.len(),
            FrameValues::File(f) => f.len,
        }
    }

    /// No value at all.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The value of frame `index`; `None` past the end. Reading the file
    /// may fail: the error names the file and the frame.
    pub fn get(&self, index: usize) -> Result<Option<f64>, SourceError> {
        match self {
            FrameValues::Memory(v) => Ok(v.get(index).copied()),
            FrameValues::File(_) if index >= self.len() => Ok(None),
            FrameValues::File(f) => KEPT.with(|kept| {
                let (blocks, clock) = &mut *kept.borrow_mut();
                *clock += 1;
                let block = index / BLOCK;
                let at = match blocks
                    .iter()
                    .position(|b| (b.table, b.block) == (f.id, block))
                {
                    Some(at) => at,
                    None => {
                        // A new block, or in place of the least recently used.
                        let at = if blocks.len() < BLOCKS_KEPT {
                            blocks.push(Kept {
                                table: f.id,
                                block,
                                used: 0,
                                values: Vec::with_capacity(BLOCK),
                            });
                            blocks.len() - 1
                        } else {
                            (0..blocks.len())
                                .min_by_key(|&k| blocks[k].used)
                                .unwrap_or(0)
                        };
                        let b = &mut blocks[at];
                        // Marked empty until read: a failed read keeps nothing.
                        (b.table, b.block) = (u64::MAX, usize::MAX);
                        let lo = block * BLOCK;
                        f.read(lo, (lo + BLOCK).min(f.len), index, &mut b.values)?;
                        (b.table, b.block) = (f.id, block);
                        at
                    }
                };
                blocks[at].used = *clock;
                Ok(Some(blocks[at].values[index % BLOCK]))
            }),
        }
    }

    /// `f(index, value)` for every frame in order, a block at a time.
    pub fn try_for_each(&self, mut f: impl FnMut(usize, f64)) -> Result<(), SourceError> {
        match self {
            FrameValues::Memory(v) => v.iter().enumerate().for_each(|(i, &x)| f(i, x)),
            FrameValues::File(file) => {
                let mut values = Vec::with_capacity(BLOCK);
                for lo in (0..file.len).step_by(BLOCK) {
                    file.read(lo, (lo + BLOCK).min(file.len), lo, &mut values)?;
                    values.iter().enumerate().for_each(|(k, &x)| f(lo + k, x));
                }
            }
        }
        Ok(())
    }

    /// Every value, in a vector: for short movies and tests.
    pub fn to_vec(&self) -> Result<Vec<f64>, SourceError> {
        let mut all = Vec::with_capacity(self.len());
        self.try_for_each(|_, x| all.push(x))?;
        Ok(all)
    }

    /// Bytes held on the heap (a table in memory; besides, a thread that
    /// looked values up in the file keeps at most
    /// `BLOCKS_KEPT × BLOCK × 8` bytes of them).
    pub fn heap_bytes(&self) -> usize {
        match self {
            FrameValues::Memory(v) => std::mem::size_of_val(&**v),
            FrameValues::File(f) => std::mem::size_of::<ValuesInFile>() + f.path.capacity(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_runs_and_look_up_as_the_list_would() {
        let lists: [Vec<i64>; 5] = [
            vec![],
            vec![7],
            (-3..100).collect(),
            vec![-3, -2, 0, 1, 5, 6, 7, 100],
            vec![4, 3, 3, 9],
        ];
        for list in lists {
            let n: FrameNumbers = list.iter().copied().collect();
            assert_eq!(n.len(), list.len());
            assert_eq!(n.iter().collect::<Vec<_>>(), list);
            for (i, v) in list.iter().enumerate() {
                assert_eq!(n.get(i), Some(*v));
            }
            assert_eq!(n.get(list.len()), None);
            assert_eq!(
                (n.first(), n.last()),
                (list.first().copied(), list.last().copied())
            );
        }
        let long = FrameNumbers::consecutive(-1000, 10_000_000);
        assert_eq!(long.get(9_999_999), Some(9_999_999 - 1000));
        assert_eq!(long, (-1000..9_999_000).collect());
        assert!(long.heap_bytes() <= 16);
    }

    #[test]
    fn values_in_a_file_read_back_as_the_table_and_fail_with_the_frame() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.bin");
        let n = 3 * BLOCK + 5;
        let raw: Vec<u32> = (0..n as u32)
            .map(|i| i.wrapping_mul(2_654_435_761))
            .collect();
        let bytes: Vec<u8> = std::iter::repeat_n(0xAB, 10)
            .chain(raw.iter().flat_map(|v| v.to_le_bytes()))
            .collect();
        std::fs::write(&path, &bytes).unwrap();
        let table = |len| {
            let file = File::open(&path).unwrap();
            FrameValues::File(Arc::new(ValuesInFile::new(
                file,
                path.clone(),
                10,
                len,
                Stored::Fraction32,
            )))
        };
        let t = table(n);
        let want: Vec<f64> = raw
            .iter()
            .map(|&v| f64::from(v) / 4_294_967_296.0)
            .collect();
        assert_eq!(t.to_vec().unwrap(), want);
        // Two places at once, backwards, from two tables: the same bits.
        let u = table(n);
        for i in (0..n).rev() {
            assert_eq!(t.get(i).unwrap(), Some(want[i]));
            assert_eq!(u.get(n - 1 - i).unwrap(), Some(want[n - 1 - i]));
        }
        assert_eq!(t.get(n).unwrap(), None);
        // A table longer than the file: its frames past the end name the frame.
        let long = table(n + 10);
        let e = long.get(n + 3).unwrap_err().to_string();
        assert!(
            e.contains("t.bin") && e.contains(&format!("frame {}", n + 3)),
            "{e}"
        );
        assert!(long.to_vec().is_err());
    }
}
