//! The contract every reader keeps: a frame ([`Frame`]), what a sequence
//! holds ([`SourceMeta`], [`SourceDetails`]), how it is opened
//! ([`OpenOptions`]), and the trait that reads it ([`FrameSource`]).

use ndarray::{Array2, ArrayViewMut2};
use std::path::PathBuf;

use super::colour::ColourInput;
use super::error::SourceError;
use super::index::{FrameNumbers, FrameValues};

/// One grey frame, shape `(height, width)`, rows top-down, values as stored.
pub type Frame = Array2<u16>;

/// What a frame sequence holds, read from its headers or side files.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SourceMeta {
    /// The file or folder the frames come from.
    pub path: PathBuf,
    /// A short name of the container: `"cine"`, `"tiff"`, `"png"`, `"bmp"`, `"jpeg"`.
    pub format: String,
    /// Number of frames that can be read (indices `0..frame_count`).
    pub frame_count: usize,
    /// Frame width, px.
    pub width: usize,
    /// Frame height, px.
    pub height: usize,
    /// Significant bits per sample (8, 10, 12, 14 or 16).
    pub bit_depth: u8,
    /// Spacing of the saved frames in frames per second (after any decimation).
    pub fps: f64,
    /// Exposure time of one frame, when known.
    pub exposure_s: Option<f64>,
    /// Camera image number of frame index 0 (negative = before the trigger).
    pub first_frame: i64,
    /// The camera image number of every readable frame, ascending.
    /// Consecutive unless the sequence has gaps (held as runs: a few bytes
    /// a gap, not a number a frame).
    pub frame_numbers: FrameNumbers,
    /// Missing image numbers as inclusive ranges `(first, last)`.
    pub gaps: Vec<(i64, i64)>,
    /// Per-frame time in seconds relative to the trigger, where the file
    /// has it (a `.cine`'s read from the file when looked up; shared, not
    /// copied, by the clones of a source and of its metadata).
    pub timestamps_s: Option<FrameValues>,
    /// Everything else the headers say (levels, flips, per-frame exposures, camera).
    pub details: SourceDetails,
}

/// Secondary metadata: what `inspect` shows beyond the contract keys.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SourceDetails {
    /// How samples are stored, e.g. `"16-bit unpacked"`, `"P10 packed"`, `"tiff 8-bit"`.
    pub container: String,
    /// Raw black level (counts) from the cine SETUP or the PCC XML.
    pub black_level: Option<i64>,
    /// Raw white level (counts) from the cine SETUP or the PCC XML.
    pub white_level: Option<i64>,
    /// Viewer flips recorded by the camera software (formats/phantom.md §8.6).
    pub flip_h: bool,
    /// The viewer flips the picture upside down (`flip_h`: left to right).
    pub flip_v: bool,
    /// Viewer rotation in degrees (+90 counter-clockwise), recorded, never applied.
    pub rotate_deg: i32,
    /// True when the reader applies `flip_h`/`flip_v` to the pixels it returns
    /// ([`OpenOptions::apply_flips`]); false means storage order.
    pub flips_applied: bool,
    /// Per-frame exposure in seconds (cine tag 1003, PCC XML EXPOSUREBLOCK).
    pub exposures_s: Option<FrameValues>,
    /// Acquisition frame rate before save decimation (cine), frames per second.
    pub acquisition_fps: Option<f64>,
    /// Save decimation (cine SETUP.fDecimation); 1 when absent.
    pub decimation: f64,
    /// Camera model text or code, software version, SETUP length (cine).
    pub camera: Option<String>,
    /// The camera software's version that wrote the cine (SETUP's SoftwareVersion).
    pub software_version: Option<u32>,
    /// Length of the cine's SETUP block, bytes.
    pub setup_length: Option<u16>,
    /// The PCC XML side file read for a folder.
    pub side_file: Option<PathBuf>,
    /// Non-fatal oddities found while opening (e.g. a corrupt ImageSize field).
    pub warnings: Vec<String>,
    /// A colour input read as grey luminance (`colour`); `None`: grey.
    pub colour: Option<ColourInput>,
    /// How a folder's frame files are named; `None` for a recording file.
    pub frame_names: Option<FrameNames>,
    /// A P10 packed cine: how its codes are returned; `None` for any other
    /// storage.
    pub p10: Option<P10Mode>,
}

/// How a folder's frame files are named: `<prefix><number>.<ext>`.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct FrameNames {
    /// What comes before the number (its sign aside).
    pub prefix: String,
    /// Digits of the number, zero-padded to this width (the manifest's
    /// `number_digits` when it gives one; the digits of the first name else).
    pub number_digits: usize,
    /// When the digits at the end of the names read two ways: which was
    /// taken, and how to take the other.
    pub note: Option<String>,
}

/// How the P10 packed 10-bit codes of a `.cine` are returned.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum P10Mode {
    /// The 10-bit codes as stored (0‥1023), like pims and ffmpeg. The default.
    #[default]
    Raw,
    /// Through Vision Research's 1024-entry linearisation table to linear
    /// 12-bit values (2‥4095), like pycine and CineFiles.jl (without their
    /// black/white rescale). `bit_depth` then reads 12.
    Linear,
}

/// Choices made when opening a source.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OpenOptions {
    /// Frame rate to use when the input carries none (a folder without a PCC
    /// XML): from the run manifest or `pipeline.toml`'s `camera.fps`.
    pub fps_fallback: Option<f64>,
    /// Apply the recorded viewer flips (`bFlipV`, `bFlipH`) to the returned
    /// pixels, i.e. show the picture "as PCC displays it". Off by default:
    /// frames come in storage order (formats/phantom.md §0.12, §8.6).
    pub apply_flips: bool,
    /// P10 packed cines: raw codes (default) or linearised.
    pub p10: P10Mode,
    /// Folders of frames: how many digits at the end of a file's name are
    /// its number (the manifest's `number_digits`); `None`: all of them,
    /// unless the names can be read two ways (`folder::number_split`).
    pub number_digits: Option<usize>,
}

/// What kind of input a path is (`input_kind`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputKind {
    /// A directory: one PCC-style image sequence, or the one recording file in it.
    Folder,
    /// A regular file named `.cine` (any case) or starting with the cine magic.
    Cine,
    /// A Photron `.mraw`, or its `.cihx` / `.cih` header.
    Photron,
}

impl SourceMeta {
    /// Time of frame `index` in seconds: the file's own time stamp where it has
    /// one, else `frame_number / fps`. Fails only when a time stamp kept in
    /// the file cannot be read (the error names the file and the frame).
    pub fn time_s(&self, index: usize) -> Result<f64, SourceError> {
        if let Some(t) = self
            .timestamps_s
            .as_ref()
            .map(|t| t.get(index))
            .transpose()?
            .flatten()
        {
            return Ok(t);
        }
        Ok(self.frame_number(index) as f64 / self.fps)
    }

    /// Bytes the per-frame index holds on the heap: image numbers, gaps,
    /// times and exposures (a `.cine`'s stay in the file; a thread that
    /// looks them up keeps a few blocks of them besides, `index`).
    pub fn index_heap_bytes(&self) -> usize {
        self.frame_numbers.heap_bytes()
            + self.gaps.capacity() * std::mem::size_of::<(i64, i64)>()
            + self
                .timestamps_s
                .as_ref()
                .map_or(0, FrameValues::heap_bytes)
            + self
                .details
                .exposures_s
                .as_ref()
                .map_or(0, FrameValues::heap_bytes)
    }

    /// What a run read from this input should say once, as a warning: a
    /// colour input read as grey, frame names whose number could be read
    /// another way.
    pub fn reading_notes(&self) -> Vec<String> {
        let d = &self.details;
        d.colour
            .iter()
            .map(|c| format!("the frames are {}", c.describe()))
            .chain(d.frame_names.iter().filter_map(|n| n.note.clone()))
            .collect()
    }

    /// How the stored samples became the grey picture returned, as
    /// space-separated words (drops.csv's `reading` column); empty when
    /// the frames are returned as stored: `bayer_<pattern>_luminance` or
    /// `rgb_luminance` (a colour input read as grey luminance), `flip_v`
    /// and `flip_h` (the viewer flips the header records, applied),
    /// `flips_not_applied` (a recording file's, not applied: storage
    /// orientation),
    /// `p10_linear` or `p10_codes` (a P10 cine's log-encoded codes
    /// linearised to 12 bits, or returned as stored).
    pub fn reading(&self) -> String {
        let d = &self.details;
        let mut words: Vec<String> = Vec::new();
        match d.colour {
            Some(ColourInput::Bayer(b)) => {
                words.push(format!("bayer_{}_luminance", b.name().to_lowercase()))
            }
            Some(ColourInput::Rgb) => words.push("rgb_luminance".into()),
            None => {}
        }
        if d.flips_applied {
            words.extend(d.flip_v.then(|| "flip_v".to_string()));
            words.extend(d.flip_h.then(|| "flip_h".to_string()));
        } else if (d.flip_v || d.flip_h) && d.frame_names.is_none() {
            // Frame files are exported as the viewer shows them: a flip
            // their side file records is no difference from what is read.
            words.push("flips_not_applied".into());
        }
        match d.p10 {
            Some(P10Mode::Linear) => words.push("p10_linear".into()),
            Some(P10Mode::Raw) => words.push("p10_codes".into()),
            None => {}
        }
        words.join(" ")
    }

    /// The camera image number of frame `index` (the index itself past the
    /// end of the list).
    pub fn frame_number(&self, index: usize) -> i64 {
        self.frame_numbers.get(index).unwrap_or(index as i64)
    }
}

/// A readable sequence of grey frames.
pub trait FrameSource: Send {
    /// The sequence's metadata.
    fn meta(&self) -> &SourceMeta;

    /// Fill `out` (shape `(height, width)`) with frame `index`.
    fn read_into(&mut self, index: usize, out: &mut Frame) -> Result<(), SourceError> {
        let (h, w) = (self.meta().height, self.meta().width);
        if out.dim() != (h, w) {
            return Err(SourceError::BufferShape {
                path: self.meta().path.clone(),
                width: w,
                got: if out.nrows() == h { out.ncols() } else { 0 },
            });
        }
        self.read_rows_into(
            index,
            0,
            &mut out.view_mut().slice_move(ndarray::s![0..h, ..]),
        )
    }

    /// Fill `out` (shape `(n, width)`) with rows `row0..row0 + n` of frame
    /// `index`. Detection reads only the band of rows near the sphere.
    fn read_rows_into(
        &mut self,
        index: usize,
        row0: usize,
        out: &mut ArrayViewMut2<u16>,
    ) -> Result<(), SourceError>;

    /// Rows `row0..row0 + n` of frame `index` as [`read_rows_into`]
    /// reads them, except that only the columns in `cols` (ranges in
    /// increasing order, not overlapping) need be filled: `out`'s other
    /// columns may keep what they held. Sources that can leave the other
    /// columns unconverted do (8- and 16-bit raw TIFF and BMP folders,
    /// 8-bit `.cine`), so that a sphere in a wide frame costs its own
    /// columns, not the sensor's (the bytes of whole rows are still read:
    /// they are contiguous in the file); the others read whole rows.
    ///
    /// [`read_rows_into`]: FrameSource::read_rows_into
    fn read_window_into(
        &mut self,
        index: usize,
        row0: usize,
        cols: &[std::ops::Range<usize>],
        out: &mut ArrayViewMut2<u16>,
    ) -> Result<(), SourceError> {
        let _ = cols;
        self.read_rows_into(index, row0, out)
    }

    /// A second handle on the same frames, for another thread to read
    /// (tracking measures chunks of one movie on several threads); `None`
    /// when the source cannot give one (the work then stays on one thread).
    fn try_clone(&self) -> Option<Box<dyn FrameSource>> {
        None
    }
}
