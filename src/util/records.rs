//! A run's per-frame records, held in memory up to a budget and past it in
//! an unnamed temporary file, so that what a long movie's tracker holds
//! does not grow with its length. Records are appended in the
//! frames' order, then read back a block at a time: walked in order,
//! updated block by block, or one at a time. A record is stored as the bits
//! of its fields, so what is read back is the same value; each kind of
//! record says how beside its type (`impl Record`, as
//! [`crate::track::FrameTrack`]'s).

use std::fs::File;

use crate::util::io::{read_at, write_at};

/// A record of a fixed number of bytes in the file.
pub trait Record: Clone {
    /// Bytes of one record.
    const BYTES: usize;
    /// Append exactly [`Self::BYTES`] bytes to `out`.
    fn put(&self, out: &mut Vec<u8>);
    /// The record from its [`Self::BYTES`] bytes.
    fn get(b: &[u8]) -> Self;
}

/// Records read or written at once from the file.
pub const BLOCK: usize = 4096;

/// Records in order, in memory while at most `memory_max`, else in a file.
pub struct Records<T> {
    /// Every record while they fit the budget; past it, those appended and
    /// not yet written (fewer than [`BLOCK`]).
    mem: Vec<T>,
    file: Option<File>,
    /// Records in the file.
    in_file: usize,
    memory_max: usize,
    /// The first read of the file that failed in [`Records::iter`], which
    /// then ended early: [`Records::check`] returns it.
    failed: std::sync::OnceLock<String>,
}

/// The records, as a list (the same text in memory and in a file).
impl<T: Record + std::fmt::Debug> std::fmt::Debug for Records<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

impl<T: Record> Records<T> {
    /// None yet; at most `memory_max` of them held in memory.
    pub fn new(memory_max: usize) -> Self {
        Records::with_capacity(0, memory_max)
    }

    /// [`Self::new`], with room for `n` records in memory (at most
    /// `memory_max`).
    pub fn with_capacity(n: usize, memory_max: usize) -> Self {
        Records {
            mem: Vec::with_capacity(n.min(memory_max)),
            file: None,
            in_file: 0,
            memory_max,
            failed: std::sync::OnceLock::new(),
        }
    }

    /// Number of records, in memory and in the file.
    pub fn len(&self) -> usize {
        self.in_file + self.mem.len()
    }

    /// No record at all.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether the records are in a file.
    pub fn spilled(&self) -> bool {
        self.file.is_some()
    }

    /// Most records held in memory before they go to a file.
    pub fn memory_max(&self) -> usize {
        self.memory_max
    }

    /// Append `r`. Past the budget, the records go to the file a block at
    /// a time (the first time, all of them).
    pub fn push(&mut self, r: T) -> std::io::Result<()> {
        if self.file.is_none() && self.mem.len() < self.memory_max {
            self.mem.push(r);
            return Ok(());
        }
        if self.file.is_none() {
            self.file = Some(tempfile::tempfile()?);
        }
        self.mem.push(r);
        if self.mem.len() >= BLOCK {
            self.flush()?;
        }
        Ok(())
    }

    /// Write the records held in memory to the file, when there is one:
    /// after the last [`Self::push`], before reading.
    pub fn flush(&mut self) -> std::io::Result<()> {
        let Some(file) = &self.file else {
            return Ok(());
        };
        // A block at a time (the first time, the whole budget is written).
        let mut bytes = Vec::with_capacity(BLOCK.min(self.mem.len()) * T::BYTES);
        for (k, block) in self.mem.chunks(BLOCK).enumerate() {
            bytes.clear();
            for r in block {
                r.put(&mut bytes);
            }
            let at = self.in_file + k * BLOCK;
            write_at(file, (at * T::BYTES) as u64, &bytes)?;
        }
        self.in_file += self.mem.len();
        self.mem.clear();
        if self.mem.capacity() > BLOCK {
            self.mem = Vec::with_capacity(BLOCK);
        }
        Ok(())
    }

    /// Records `lo..hi` (copied from memory, or read from the file).
    pub fn block(&self, lo: usize, hi: usize) -> std::io::Result<Vec<T>> {
        match &self.file {
            None => Ok(self.mem[lo..hi].to_vec()),
            Some(file) => {
                assert!(self.mem.is_empty(), "records read before their flush");
                let mut bytes = vec![0u8; (hi - lo) * T::BYTES];
                read_at(file, (lo * T::BYTES) as u64, &mut bytes)?;
                Ok(bytes.chunks_exact(T::BYTES).map(T::get).collect())
            }
        }
    }

    /// `f` on records `lo..hi`: those in memory as they are, those in the
    /// file read first.
    pub fn with_block<R>(
        &self,
        lo: usize,
        hi: usize,
        f: impl FnOnce(&[T]) -> R,
    ) -> std::io::Result<R> {
        match &self.file {
            None => Ok(f(&self.mem[lo..hi])),
            Some(_) => Ok(f(&self.block(lo, hi)?)),
        }
    }

    /// Record `i`.
    pub fn get(&self, i: usize) -> std::io::Result<T> {
        Ok(self.block(i, i + 1)?.remove(0))
    }

    /// Replace record `i`.
    pub fn set(&mut self, i: usize, r: T) -> std::io::Result<()> {
        match &self.file {
            None => self.mem[i] = r,
            Some(file) => {
                let mut bytes = Vec::with_capacity(T::BYTES);
                r.put(&mut bytes);
                write_at(file, (i * T::BYTES) as u64, &bytes)?;
            }
        }
        Ok(())
    }

    /// The records in order, a block read at a time. A read of the file
    /// that fails ends the walk early and is kept for [`Self::check`]: what
    /// was made from the records is used only after that check.
    pub fn iter(&self) -> impl Iterator<Item = T> + '_ {
        // In memory, each record copied as it is taken, not a block at a
        // time; in a file, a block at a time.
        let (in_memory, n) = match self.file {
            None => (&self.mem[..], 0),
            Some(_) => (&[][..], self.len()),
        };
        let from_file = (0..n)
            .step_by(BLOCK)
            .map_while(move |lo| match self.block(lo, (lo + BLOCK).min(n)) {
                Ok(block) => Some(block),
                Err(e) => {
                    let _ = self.failed.set(e.to_string());
                    None
                }
            })
            .flatten();
        in_memory.iter().cloned().chain(from_file)
    }

    /// The first failed read of [`Self::iter`], if any.
    pub fn check(&self) -> std::io::Result<()> {
        match self.failed.get() {
            Some(e) => Err(std::io::Error::other(format!(
                "reading a temporary file of per-frame records back: {e}"
            ))),
            None => Ok(()),
        }
    }

    /// `f(first index, block)` on the records a block at a time (all at
    /// once in memory), each block written back after it.
    pub fn update<E: From<std::io::Error>>(
        &mut self,
        mut f: impl FnMut(usize, &mut [T]) -> Result<(), E>,
    ) -> Result<(), E> {
        if self.file.is_none() {
            return f(0, &mut self.mem);
        }
        let n = self.len();
        for lo in (0..n).step_by(BLOCK) {
            let hi = (lo + BLOCK).min(n);
            let mut block = self.block(lo, hi)?;
            f(lo, &mut block)?;
            let mut bytes = Vec::with_capacity(block.len() * T::BYTES);
            for r in &block {
                r.put(&mut bytes);
            }
            write_at(
                self.file.as_ref().expect("a file"),
                (lo * T::BYTES) as u64,
                &bytes,
            )?;
        }
        Ok(())
    }
}

/// Writes a record's fields as their bits, little-endian.
pub struct Put<'a>(pub &'a mut Vec<u8>);

impl Put<'_> {
    /// Write a byte.
    pub fn u8(&mut self, v: u8) {
        self.0.push(v);
    }
    /// Write a `u32`, little-endian.
    pub fn u32(&mut self, v: u32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    /// Write a `u64`, little-endian.
    pub fn u64(&mut self, v: u64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    /// Write an `f64` as its bits, little-endian.
    pub fn f64(&mut self, v: f64) {
        self.u64(v.to_bits());
    }
}

/// Reads back what [`Put`] wrote, in the same order.
pub struct Take<'a>(pub &'a [u8]);

impl Take<'_> {
    fn bytes<const N: usize>(&mut self) -> [u8; N] {
        let (head, rest) = self.0.split_at(N);
        self.0 = rest;
        head.try_into().expect("N bytes")
    }
    /// Read a byte.
    pub fn u8(&mut self) -> u8 {
        self.bytes::<1>()[0]
    }
    /// Read a `u32`, little-endian.
    pub fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.bytes())
    }
    /// Read a `u64`, little-endian.
    pub fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.bytes())
    }
    /// Read an `f64` from its bits, little-endian.
    pub fn f64(&mut self) -> f64 {
        f64::from_bits(self.u64())
    }
}
