//! Tracks kept on a shelf between a job's two looks at its runs.
//!
//! With `camera.infer_setups`, [`crate::pipeline::prepare`] tracks every run
//! without a `setup` to read its scene; the runs are then processed by
//! camera set-up, each set-up's runs tracked together. Tracking is most of
//! a short drop's cost (its background and surface line), so each track is
//! kept from the first look for the second instead of being made again.
//! A track's bulk — its background levels (4 bytes a pixel) and its
//! per-frame records when they are in memory — goes to one unnamed
//! temporary file for the job (`tempfile`, in `TMPDIR`) and is read back
//! when the run's set-up is processed, so what the job holds between the
//! two looks is a few hundred bytes a run, not a background a run. The
//! values come back as the bits they were written from: the track read
//! back is the track that was put.

use std::fs::File;
use std::sync::atomic::{AtomicU64, Ordering};

use crate::track::{FrameTrack, Track};
use crate::util::io::{read_at, write_at};
use crate::util::records::{Record, Records};

/// One job's shelf: an unnamed temporary file written at the end.
pub struct Shelf {
    file: File,
    end: AtomicU64,
}

/// A track on a [`Shelf`]: all of it held but its background levels and,
/// when they were in memory, its records, which are in the shelf's file.
pub struct ShelvedTrack {
    track: Track,
    /// Offset of its bytes in the file: the levels, then the records.
    at: u64,
    levels: usize,
    /// Records in the file (0 when they stayed in their own: a long movie's).
    records: usize,
    records_memory_max: usize,
}

impl Shelf {
    /// An empty shelf (its file created).
    pub fn new() -> std::io::Result<Shelf> {
        Ok(Shelf {
            file: tempfile::tempfile()?,
            end: AtomicU64::new(0),
        })
    }

    /// Put `track` on the shelf (from any thread).
    pub fn put(&self, mut track: Track) -> std::io::Result<ShelvedTrack> {
        let levels = std::mem::take(&mut track.background.levels);
        let in_memory = !track.frames.spilled();
        let records_memory_max = track.frames.memory_max();
        let records = if in_memory { track.frames.len() } else { 0 };
        let n_levels = levels.len();
        let mut bytes = Vec::with_capacity(4 * n_levels + records * FrameTrack::BYTES);
        for v in &levels {
            bytes.extend_from_slice(&v.to_bits().to_le_bytes());
        }
        drop(levels);
        if in_memory {
            for r in track.frames.iter() {
                r.put(&mut bytes);
            }
            track.frames = Records::new(records_memory_max);
        }
        let at = self.end.fetch_add(bytes.len() as u64, Ordering::Relaxed);
        write_at(&self.file, at, &bytes)?;
        Ok(ShelvedTrack {
            track,
            at,
            levels: n_levels,
            records,
            records_memory_max,
        })
    }

    /// The track `s` was made from, read back.
    pub fn take(&self, s: ShelvedTrack) -> std::io::Result<Track> {
        let ShelvedTrack {
            mut track,
            at,
            levels,
            records,
            records_memory_max,
        } = s;
        let mut bytes = vec![0u8; 4 * levels + records * FrameTrack::BYTES];
        read_at(&self.file, at, &mut bytes)?;
        let (level_bytes, record_bytes) = bytes.split_at(4 * levels);
        track.background.levels = level_bytes
            .chunks_exact(4)
            .map(|b| f32::from_bits(u32::from_le_bytes([b[0], b[1], b[2], b[3]])))
            .collect();
        if records > 0 {
            let mut frames = Records::with_capacity(records, records_memory_max);
            for b in record_bytes.chunks_exact(FrameTrack::BYTES) {
                frames.push(FrameTrack::get(b))?;
            }
            track.frames = frames;
        }
        Ok(track)
    }
}
