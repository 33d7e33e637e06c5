//! The XML side file Phantom Camera Control writes beside an image export
//! (formats/phantom.md §12.4): root `<chd>` with `CineFileHeader`,
//! `BitmapInfoHeader`, `CameraSetup`, `TIMEBLOCK`, `EXPOSUREBLOCK`.
//!
//! Times in the XML are local wall-clock: `<Date>Sat Aug 24 2019</Date>` and
//! `<Time>14:53:32.328 240.68</Time>` (`HH:MM:SS.mmm` then the microseconds
//! within that millisecond, 10 ns resolution; a trailing ` E` marks an active
//! event input). Per-frame times are taken from `TIMEBLOCK/Time[@frame]` only —
//! `CineFileHeader/TriggerTime/Time` is the trigger, not a frame — and are
//! returned relative to the trigger, so the local time zone cancels.
//!
//! The file is read as a stream ([`read`]): a long recording's TIMEBLOCK
//! and EXPOSUREBLOCK (~120 bytes a frame) are never held whole, only the
//! values taken from them.

use std::collections::HashMap;
use std::io::{self, BufRead, Read};

use quick_xml::events::{BytesStart, Event};
use quick_xml::{Reader, XmlVersion};

/// What dropscope takes from a PCC XML. Fields are `None` when absent.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PccXml {
    /// `CineFileHeader/FirstImageNo`: image number of the first exported image.
    pub first_image_no: Option<i64>,
    /// `CineFileHeader/ImageCount`: number of exported images.
    pub image_count: Option<u64>,
    /// `BitmapInfoHeader/biWidth`: image width, px.
    pub width: Option<u32>,
    /// `BitmapInfoHeader/biHeight`: image height, px.
    pub height: Option<u32>,
    /// `BitmapInfoHeader/biBitCount` of the exported images.
    pub bit_count: Option<u32>,
    /// `CameraSetup/FrameRateDouble`, else `CameraSetup/FrameRate`, frames/s.
    pub fps: Option<f64>,
    /// `CameraSetup/ShutterNs` (ns), else `Shutter` (µs), in seconds.
    pub exposure_s: Option<f64>,
    /// `CameraSetup/RealBPP`: significant bits of a sample.
    pub real_bpp: Option<u8>,
    /// `CameraSetup/BlackLevel`: the raw black level, counts.
    pub black_level: Option<i64>,
    /// `CameraSetup/WhiteLevel`: the raw white level, counts.
    pub white_level: Option<i64>,
    /// `CameraSetup/bFlipH`: the viewer flips the picture left to right.
    pub flip_h: Option<bool>,
    /// `CameraSetup/bFlipV`: the viewer flips the picture upside down.
    pub flip_v: Option<bool>,
    /// `(image number, seconds after the trigger)` from `TIMEBLOCK`, in file order.
    pub times: Vec<(i64, f64)>,
    /// `(image number, exposure seconds)` from `EXPOSUREBLOCK`.
    pub exposures: Vec<(i64, f64)>,
}

/// Most frames a side file may list, in its TIMEBLOCK or its
/// EXPOSUREBLOCK: what is kept of them is 16 bytes a frame each (so at
/// most 64 MiB a block), whatever the file's length.
pub const MAX_XML_FRAMES: usize = 4 << 20;

/// Deepest element nesting accepted. PCC's files nest 4 deep.
pub const MAX_XML_DEPTH: usize = 64;

/// Longest single piece of the file — a tag, a text, a comment — in
/// bytes: the reader holds one piece whole. PCC's longest is a few
/// hundred bytes.
pub const MAX_XML_PIECE_BYTES: u64 = 1 << 20;

/// Most bytes of different TIMEBLOCK dates kept (PCC writes one date a
/// day of recording, 15 bytes).
const MAX_DATE_BYTES: usize = 16 << 20;

/// Parse a PCC XML document held in memory: [`read`] of its bytes.
pub fn parse(text: &str) -> Result<PccXml, String> {
    read(text.as_bytes())
}

/// Read a PCC XML document as a stream: one piece at a time, nothing of
/// it held whole and no tree built, so memory does not grow with the file
/// beyond the 16 bytes a frame of [`PccXml::times`] and
/// [`PccXml::exposures`]. Errors say what is wrong (not XML — with the
/// byte where — nested too deep, a piece too long, too many frames, wrong
/// root, a value that is not a number or not a possible frame rate or
/// exposure); missing optional elements are `None`. When a file holds
/// several of these faults, the first in this order is the one told:
/// the file's structure as far as it was read (XML, depth, lengths), then
/// the root, the values in [`PccXml`]'s order with the trigger and the two
/// blocks before the plain numbers.
///
/// An element's text is all its text (text, entities, CDATA) before its
/// first child element, across comments and processing instructions
/// (`<ShutterNs>50<!---->000</ShutterNs>` is 50000 ns, not 50). A value
/// given twice (in one block, or in a repeated `CineFileHeader`,
/// `BitmapInfoHeader` or `CameraSetup`) must be the same both times: a
/// side file that contradicts itself is refused naming the element. Of the
/// trigger and of a repeated TIMEBLOCK or EXPOSUREBLOCK, the first counts.
pub fn read(input: impl BufRead) -> Result<PccXml, String> {
    read_limited(input, MAX_XML_FRAMES)
}

fn read_limited(input: impl BufRead, max_frames: usize) -> Result<PccXml, String> {
    let mut reader = Reader::from_reader(Pieces {
        inner: input,
        taken: 0,
        too_long: false,
    });
    reader.config_mut().check_comments = true;
    let mut walk = Walk::new(max_frames);
    let mut buf = Vec::new();
    loop {
        reader.get_mut().taken = 0;
        let at = reader.buffer_position();
        let event = match reader.read_event_into(&mut buf) {
            Ok(event) => event,
            Err(quick_xml::Error::Io(_)) if reader.get_ref().too_long => {
                return Err(format!(
                    "a tag, text or comment longer than {} MiB at byte {at}: not a PCC side file",
                    MAX_XML_PIECE_BYTES >> 20
                ))
            }
            Err(quick_xml::Error::Io(e)) => return Err(format!("reading it: {e}")),
            Err(e) => {
                return Err(format!(
                    "not valid XML at byte {}: {e}",
                    reader.error_position()
                ))
            }
        };
        if matches!(event, Event::Eof) {
            return walk.finish();
        }
        walk.event(event, at)?;
        buf.clear();
    }
}

/// The input, refusing a piece longer than [`MAX_XML_PIECE_BYTES`]: bytes
/// taken since the reader's last event are counted.
struct Pieces<R> {
    inner: R,
    taken: u64,
    too_long: bool,
}

impl<R: BufRead> Read for Pieces<R> {
    fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
        let n = {
            let b = self.fill_buf()?;
            let n = b.len().min(out.len());
            out[..n].copy_from_slice(&b[..n]);
            n
        };
        self.consume(n);
        Ok(n)
    }
}

impl<R: BufRead> BufRead for Pieces<R> {
    fn fill_buf(&mut self) -> io::Result<&[u8]> {
        if self.taken > MAX_XML_PIECE_BYTES {
            self.too_long = true;
            return Err(io::Error::other("a piece of the file is too long"));
        }
        // At most 64 kB at once, so that the count stops a long piece
        // early whatever the input's own buffer.
        let b = self.inner.fill_buf()?;
        Ok(&b[..b.len().min(1 << 16)])
    }

    fn consume(&mut self, n: usize) {
        self.taken += n as u64;
        self.inner.consume(n);
    }
}

/// The elements dropscope reads values from: the first of each name
/// under the root.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Block {
    Header,
    Bitmap,
    Setup,
    Times,
    Exposures,
}

const BLOCKS: [(Block, &str); 5] = [
    (Block::Header, "CineFileHeader"),
    (Block::Bitmap, "BitmapInfoHeader"),
    (Block::Setup, "CameraSetup"),
    (Block::Times, "TIMEBLOCK"),
    (Block::Exposures, "EXPOSUREBLOCK"),
];

/// The single values read, each the first element of its name in its block.
const FIELDS: [(Block, &str); 14] = [
    (Block::Header, "FirstImageNo"),
    (Block::Header, "ImageCount"),
    (Block::Bitmap, "biWidth"),
    (Block::Bitmap, "biHeight"),
    (Block::Bitmap, "biBitCount"),
    (Block::Setup, "FrameRateDouble"),
    (Block::Setup, "FrameRate"),
    (Block::Setup, "ShutterNs"),
    (Block::Setup, "Shutter"),
    (Block::Setup, "RealBPP"),
    (Block::Setup, "BlackLevel"),
    (Block::Setup, "WhiteLevel"),
    (Block::Setup, "bFlipH"),
    (Block::Setup, "bFlipV"),
];

/// What an open element is to the walk.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Role {
    Root,
    Block(Block),
    /// `FIELDS[i]`.
    Field(usize),
    /// `FIELDS[i]` again: its text must be the first's.
    Repeat(usize),
    /// `CineFileHeader/TriggerTime`, its `Date` and its `Time`.
    Trigger,
    TriggerDate,
    TriggerClock,
    /// A TIMEBLOCK `Date` or `Time`, an EXPOSUREBLOCK `Exp`, of a frame.
    Date(i64),
    Time(i64),
    Exp(i64),
    /// Nothing is read from it.
    Other,
}

impl Role {
    fn wants_text(self) -> bool {
        !matches!(
            self,
            Role::Root | Role::Block(_) | Role::Trigger | Role::Other
        )
    }
}

struct Level {
    name: String,
    role: Role,
    /// Its first text so far, while no child has ended it.
    text: String,
    text_open: bool,
}

/// The TIMEBLOCK's dates listed so far, as runs: frames
/// `first..first + len` listed in a row with one date text. A time takes
/// the most recent date listed for its frame.
#[derive(Default)]
struct Dates {
    runs: Vec<(i64, u64, u32)>,
    texts: Vec<String>,
    ids: HashMap<String, u32>,
    text_bytes: usize,
}

impl Dates {
    fn push(&mut self, frame: i64, text: String, max_runs: usize) -> Result<(), String> {
        let same = |r: &(i64, u64, u32)| self.texts[r.2 as usize] == text;
        if let Some(last) = self.runs.last() {
            let next = i64::try_from(last.1)
                .ok()
                .and_then(|len| last.0.checked_add(len));
            if next == Some(frame) && same(last) {
                if let Some(last) = self.runs.last_mut() {
                    last.1 += 1;
                }
                return Ok(());
            }
        }
        if self.runs.len() >= max_runs {
            return Err(too_many("TIMEBLOCK", max_runs));
        }
        let id = match self.ids.get(&text) {
            Some(&id) => id,
            None => {
                self.text_bytes += text.len();
                if self.text_bytes > MAX_DATE_BYTES {
                    return Err(format!(
                        "TIMEBLOCK dates: more than {} MiB of different ones, not a PCC side file",
                        MAX_DATE_BYTES >> 20
                    ));
                }
                let id = self.texts.len() as u32;
                self.texts.push(text.clone());
                self.ids.insert(text, id);
                id
            }
        };
        self.runs.push((frame, 1, id));
        Ok(())
    }

    fn of(&self, frame: i64) -> Option<&str> {
        self.runs
            .iter()
            .rev()
            .find(|(first, len, _)| {
                frame
                    .checked_sub(*first)
                    .is_some_and(|k| k >= 0 && (k as u64) < *len)
            })
            .map(|r| self.texts[r.2 as usize].as_str())
    }
}

fn too_many(block: &str, max: usize) -> String {
    format!("{block} lists more than {max} frames: more than dropscope reads from a side file")
}

/// The walk through the document's events, keeping only what
/// [`PccXml`] needs.
struct Walk {
    max_frames: usize,
    stack: Vec<Level>,
    /// The root element's name, once seen.
    root: Option<String>,
    seen_decl_or_other: bool,
    blocks_seen: [bool; 5],
    /// The text of each of [`FIELDS`], trimmed; `Some` from its start.
    fields: [Option<String>; 14],
    /// A second value of a field that differs from the first, by field.
    conflicts: [Option<String>; 14],
    trigger_seen: bool,
    trigger_date: Option<String>,
    trigger_clock: Option<String>,
    trigger: Option<Result<LocalInstant, String>>,
    header_done: bool,
    dates: Dates,
    /// Frame times relative to the origin, once it is known; before (no
    /// CineFileHeader yet), the instants themselves.
    times: Vec<(i64, f64)>,
    instants: Vec<(i64, LocalInstant)>,
    first_instant: Option<LocalInstant>,
    times_error: Option<String>,
    exposures: Vec<(i64, f64)>,
    exposures_error: Option<String>,
}

impl Walk {
    fn new(max_frames: usize) -> Self {
        Walk {
            max_frames,
            stack: Vec::new(),
            root: None,
            seen_decl_or_other: false,
            blocks_seen: [false; 5],
            fields: Default::default(),
            conflicts: Default::default(),
            trigger_seen: false,
            trigger_date: None,
            trigger_clock: None,
            trigger: None,
            header_done: false,
            dates: Dates::default(),
            times: Vec::new(),
            instants: Vec::new(),
            first_instant: None,
            times_error: None,
            exposures: Vec::new(),
            exposures_error: None,
        }
    }

    fn event(&mut self, event: Event<'_>, at: u64) -> Result<(), String> {
        let invalid = |what: &str| format!("not valid XML at byte {at}: {what}");
        let first = !self.seen_decl_or_other;
        self.seen_decl_or_other = true;
        match event {
            Event::Start(e) => self.start(&e, false, at)?,
            Event::Empty(e) => {
                self.start(&e, true, at)?;
                self.end();
            }
            Event::End(_) => {
                if self.stack.is_empty() {
                    return Err(invalid("an end tag outside the root element"));
                }
                self.end();
            }
            Event::Text(t) => {
                let t = t.xml10_content();
                if self.stack.is_empty() {
                    if !t.bytes().all(|b| matches!(b, b' ' | b'\t' | b'\r' | b'\n')) {
                        return Err(invalid("text outside the root element"));
                    }
                } else {
                    self.text(&t, at)?;
                }
            }
            Event::CData(t) => {
                if self.stack.is_empty() {
                    return Err(invalid("CDATA outside the root element"));
                }
                self.text(&t.xml10_content(), at)?;
            }
            Event::GeneralRef(r) => {
                if self.stack.is_empty() {
                    return Err(invalid("a reference outside the root element"));
                }
                let name = r.xml10_content();
                let c = r.resolve_char_ref().map_err(|e| invalid(&e.to_string()))?;
                let mut one = [0u8; 4];
                let s = match c {
                    Some(c) => &*c.encode_utf8(&mut one),
                    None => quick_xml::escape::resolve_xml_entity(&name)
                        .ok_or_else(|| invalid(&format!("unknown entity &{name};")))?,
                };
                self.text(s, at)?;
            }
            // A value runs on across a comment or a processing instruction.
            Event::Comment(_) | Event::PI(_) => {}
            Event::Decl(_) if first => {}
            Event::Decl(_) => return Err(invalid("an XML declaration not at the start")),
            Event::DocType(_) => {
                return Err(invalid(
                    "a DTD (<!DOCTYPE>), which a PCC side file never has",
                ))
            }
            Event::Eof => {}
        }
        Ok(())
    }

    /// A piece of the open element's text; a value read is at most
    /// [`MAX_XML_PIECE_BYTES`] long, however many pieces make it.
    fn text(&mut self, t: &str, at: u64) -> Result<(), String> {
        if let Some(level) = self.stack.last_mut() {
            if level.text_open && level.role.wants_text() {
                if (level.text.len() + t.len()) as u64 > MAX_XML_PIECE_BYTES {
                    return Err(format!(
                        "<{}> holds more than {} MiB of text (at byte {at}): not a PCC side file",
                        level.name,
                        MAX_XML_PIECE_BYTES >> 20
                    ));
                }
                level.text.push_str(t);
            }
        }
        Ok(())
    }

    fn end_text(&mut self) {
        if let Some(level) = self.stack.last_mut() {
            level.text_open = false;
        }
    }

    fn start(&mut self, e: &BytesStart<'_>, empty: bool, at: u64) -> Result<(), String> {
        if self.stack.is_empty() && self.root.is_some() {
            return Err(format!(
                "not valid XML at byte {at}: a second root element <{}>",
                e.name().as_ref()
            ));
        }
        if !empty && self.stack.len() >= MAX_XML_DEPTH {
            return Err(format!(
                "elements nested more than {MAX_XML_DEPTH} deep (at byte {at}): not a PCC side file"
            ));
        }
        // Every attribute is checked (quoted, not repeated, known
        // references); `frame` is kept.
        let mut frame = None;
        for a in e.attributes() {
            let a = a.map_err(|err| format!("not valid XML at byte {at}: {err}"))?;
            let value = a
                .normalized_value(XmlVersion::Implicit1_0)
                .map_err(|err| format!("not valid XML at byte {at}: {err}"))?;
            if a.key.as_ref() == "frame" {
                frame = Some(value.into_owned());
            }
        }
        self.end_text();
        let name = e.local_name().as_ref().to_string();
        let role = self.role_of(&name, frame);
        self.stack.push(Level {
            name,
            role,
            text: String::new(),
            text_open: true,
        });
        Ok(())
    }

    /// The role of a new element named `name` under the open one.
    fn role_of(&mut self, name: &str, frame: Option<String>) -> Role {
        let parent = match self.stack.last() {
            None => {
                self.root = Some(name.to_string());
                return if name == "chd" {
                    Role::Root
                } else {
                    Role::Other
                };
            }
            Some(p) => p.role,
        };
        let field = |fields: &mut [Option<String>; 14], block| {
            let i = FIELDS.iter().position(|f| *f == (block, name))?;
            if fields[i].is_some() {
                return Some(Role::Repeat(i));
            }
            fields[i] = Some(String::new());
            Some(Role::Field(i))
        };
        match parent {
            Role::Root => {
                let Some(i) = BLOCKS.iter().position(|b| b.1 == name) else {
                    return Role::Other;
                };
                let block = BLOCKS[i].0;
                // A repeated header or set-up is read again, its values
                // held to the first's; a repeated time or exposure block
                // is not read.
                if std::mem::replace(&mut self.blocks_seen[i], true)
                    && matches!(block, Block::Times | Block::Exposures)
                {
                    return Role::Other;
                }
                Role::Block(block)
            }
            Role::Block(Block::Header) if name == "TriggerTime" => {
                if std::mem::replace(&mut self.trigger_seen, true) {
                    Role::Other
                } else {
                    Role::Trigger
                }
            }
            Role::Block(b @ (Block::Header | Block::Bitmap | Block::Setup)) => {
                field(&mut self.fields, b).unwrap_or(Role::Other)
            }
            Role::Trigger if name == "Date" && self.trigger_date.is_none() => {
                self.trigger_date = Some(String::new());
                Role::TriggerDate
            }
            Role::Trigger if name == "Time" && self.trigger_clock.is_none() => {
                self.trigger_clock = Some(String::new());
                Role::TriggerClock
            }
            // Every element of the TIMEBLOCK has a frame attribute.
            Role::Block(Block::Times) if self.times_error.is_none() => {
                match frame_number(name, frame.as_deref()) {
                    Err(e) => {
                        self.times_error = Some(e);
                        Role::Other
                    }
                    Ok(f) if name == "Date" => Role::Date(f),
                    Ok(f) if name == "Time" => Role::Time(f),
                    Ok(_) => Role::Other,
                }
            }
            Role::Block(Block::Exposures) if name == "Exp" && self.exposures_error.is_none() => {
                match frame_number(name, frame.as_deref()) {
                    Err(e) => {
                        self.exposures_error = Some(e);
                        Role::Other
                    }
                    Ok(f) => Role::Exp(f),
                }
            }
            _ => Role::Other,
        }
    }

    /// The open element ends: what it held is kept.
    fn end(&mut self) {
        let Some(level) = self.stack.pop() else {
            return;
        };
        let text = level.text;
        match level.role {
            Role::Block(Block::Header) => self.header_done = true,
            Role::Field(i) => self.fields[i] = Some(text.trim().to_string()),
            Role::Repeat(i) => {
                let first = self.fields[i].as_deref().unwrap_or("");
                if text.trim() != first && self.conflicts[i].is_none() {
                    self.conflicts[i] = Some(format!(
                        "<{}> is given twice, as {first:?} and {:?}: the side file contradicts \
                         itself (which value holds is unknown); correct it",
                        FIELDS[i].1,
                        text.trim()
                    ));
                }
            }
            Role::TriggerDate => self.trigger_date = Some(text),
            Role::TriggerClock => self.trigger_clock = Some(text),
            Role::Trigger => {
                let d = self.trigger_date.as_deref().unwrap_or("");
                let tm = self.trigger_clock.as_deref().unwrap_or("");
                self.trigger = Some(
                    local_seconds(d, tm)
                        .ok_or_else(|| format!("TriggerTime {d:?} {tm:?} is not a PCC date/time")),
                );
            }
            Role::Date(frame) if self.times_error.is_none() => {
                if let Err(e) = self.dates.push(frame, text, self.max_frames) {
                    self.times_error = Some(e);
                }
            }
            Role::Time(frame) if self.times_error.is_none() => {
                if let Err(e) = self.time(frame, &text) {
                    self.times_error = Some(e);
                }
            }
            Role::Exp(frame) if self.exposures_error.is_none() => {
                let us: Result<f64, _> = text.trim().parse();
                match us {
                    Err(_) => {
                        self.exposures_error =
                            Some(format!("EXPOSUREBLOCK frame={frame} is not a number"))
                    }
                    Ok(_) if self.exposures.len() >= self.max_frames => {
                        self.exposures_error = Some(too_many("EXPOSUREBLOCK", self.max_frames))
                    }
                    Ok(us) => self.exposures.push((frame, us * 1e-6)),
                }
            }
            _ => {}
        }
    }

    /// A TIMEBLOCK `Time` of `frame`: its instant from the most recent date
    /// of the frame, relative to the origin when it is known.
    fn time(&mut self, frame: i64, value: &str) -> Result<(), String> {
        let date = self
            .dates
            .of(frame)
            .ok_or_else(|| format!("TIMEBLOCK Time frame={frame} has no Date"))?;
        let t = local_seconds(date, value).ok_or_else(|| {
            format!("TIMEBLOCK frame={frame}: {date:?} {value:?} is not a PCC date/time")
        })?;
        if self.times.len() + self.instants.len() >= self.max_frames {
            return Err(too_many("TIMEBLOCK", self.max_frames));
        }
        let first = *self.first_instant.get_or_insert(t);
        // The origin is the header's trigger, or without one the first
        // listed frame: known once the header has ended (an erroneous
        // trigger fails the parse, whatever the times).
        let origin = match (&self.trigger, self.header_done) {
            (_, false) => None,
            (Some(Ok(trigger)), true) => Some(*trigger),
            (Some(Err(_)) | None, true) => Some(first),
        };
        match origin {
            Some(o) => self.times.push((frame, t.since(o))),
            None => self.instants.push((frame, t)),
        }
        Ok(())
    }

    fn finish(self) -> Result<PccXml, String> {
        if let Some(open) = self.stack.last() {
            return Err(format!(
                "not valid XML: the file ends inside <{}> (cut short?)",
                open.name
            ));
        }
        let Some(root) = self.root.as_deref() else {
            return Err("not valid XML: no root element".into());
        };
        if root != "chd" {
            return Err(format!("root element is <{root}>, not PCC's <chd>"));
        }
        if let Some(c) = self.conflicts.iter().flatten().next() {
            return Err(c.clone());
        }
        let text_of = |name: &str| -> Option<String> {
            FIELDS
                .iter()
                .position(|f| f.1 == name)
                .and_then(|i| self.fields[i].clone())
        };
        fn num<T: std::str::FromStr>(v: Option<String>, name: &str) -> Result<Option<T>, String> {
            match v {
                None => Ok(None),
                Some(s) if s.is_empty() => Ok(None),
                Some(s) => s
                    .parse::<T>()
                    .map(Some)
                    .map_err(|_| format!("<{name}> holds {s:?}, not a number")),
            }
        }
        let boolean = |v: Option<String>| {
            v.and_then(|s| match s.as_str() {
                "true" | "1" => Some(true),
                "false" | "0" => Some(false),
                _ => None,
            })
        };
        // A frame rate or exposure that is there but impossible is an error,
        // never replaced by another value.
        let positive = |name: &str| -> Result<Option<f64>, String> {
            match num::<f64>(text_of(name), name)? {
                Some(v) if !(v.is_finite() && v > 0.0) => Err(format!(
                    "<{name}> holds {v}: it must be a finite number above 0"
                )),
                v => Ok(v),
            }
        };
        let fps = match positive("FrameRateDouble")? {
            Some(f) => Some(f),
            None => positive("FrameRate")?,
        };
        let exposure_s = match positive("ShutterNs")? {
            Some(ns) => Some(ns * 1e-9),
            None => positive("Shutter")?.map(|us| us * 1e-6),
        };
        let trigger = self.trigger.clone().transpose()?;
        if let Some(e) = self.times_error {
            return Err(e);
        }
        // Relative to the trigger; without one, to the first listed frame.
        let times = match trigger.or(self.first_instant) {
            Some(origin) if !self.instants.is_empty() => {
                let mut times: Vec<(i64, f64)> = self
                    .instants
                    .iter()
                    .map(|(f, t)| (*f, t.since(origin)))
                    .collect();
                times.extend_from_slice(&self.times);
                times
            }
            _ => self.times,
        };
        if let Some(e) = self.exposures_error {
            return Err(e);
        }
        Ok(PccXml {
            first_image_no: num(text_of("FirstImageNo"), "FirstImageNo")?,
            image_count: num(text_of("ImageCount"), "ImageCount")?,
            width: num(text_of("biWidth"), "biWidth")?,
            height: num(text_of("biHeight"), "biHeight")?,
            bit_count: num(text_of("biBitCount"), "biBitCount")?,
            fps,
            exposure_s,
            real_bpp: num(text_of("RealBPP"), "RealBPP")?,
            black_level: num(text_of("BlackLevel"), "BlackLevel")?,
            white_level: num(text_of("WhiteLevel"), "WhiteLevel")?,
            flip_h: boolean(text_of("bFlipH")),
            flip_v: boolean(text_of("bFlipV")),
            times,
            exposures: self.exposures,
        })
    }
}

/// The `frame` attribute of a block's element `name`.
fn frame_number(name: &str, frame: Option<&str>) -> Result<i64, String> {
    let a = frame.ok_or_else(|| format!("<{name}> in a block has no frame attribute"))?;
    a.trim()
        .parse()
        .map_err(|_| format!("frame attribute {a:?} is not an integer"))
}

/// A local wall-clock instant split into whole and fractional seconds, so
/// differences keep 10 ns resolution (an f64 of ~1.6e9 s would not).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalInstant {
    /// Whole seconds since 1970-01-01 00:00 local time.
    pub whole_s: i64,
    /// Fraction of a second, `0 ≤ frac_s < 1` (up to 1.001 with a leap second).
    pub frac_s: f64,
}

impl LocalInstant {
    /// `self − origin` in seconds.
    pub fn since(self, origin: LocalInstant) -> f64 {
        (self.whole_s - origin.whole_s) as f64 + (self.frac_s - origin.frac_s)
    }
}

/// The instant of a PCC `Date` + `Time` pair: `"Sat Aug 24 2019"`,
/// `"14:53:32.328 240.68"` (optional trailing `E`).
pub fn local_seconds(date: &str, time: &str) -> Option<LocalInstant> {
    let mut d = date.split_whitespace();
    let _weekday = d.next()?;
    let month = match d.next()? {
        "Jan" => 1,
        "Feb" => 2,
        "Mar" => 3,
        "Apr" => 4,
        "May" => 5,
        "Jun" => 6,
        "Jul" => 7,
        "Aug" => 8,
        "Sep" => 9,
        "Oct" => 10,
        "Nov" => 11,
        "Dec" => 12,
        _ => return None,
    };
    let day: i64 = d.next()?.parse().ok()?;
    let year: i64 = d.next()?.parse().ok()?;
    if !(1..=31).contains(&day) || !(1900..=9999).contains(&year) {
        return None;
    }
    let mut t = time.split_whitespace();
    let hms = t.next()?;
    let micro: f64 = match t.next() {
        Some("E") | None => 0.0,
        Some(u) => u.parse().ok()?,
    };
    if !(0.0..1000.0).contains(&micro) {
        return None;
    }
    let mut parts = hms.split(':');
    let h: i64 = parts.next()?.parse().ok()?;
    let m: i64 = parts.next()?.parse().ok()?;
    let s: f64 = parts.next()?.parse().ok()?;
    if parts.next().is_some()
        || !(0..24).contains(&h)
        || !(0..60).contains(&m)
        || !(0.0..61.0).contains(&s)
    {
        return None;
    }
    let days = days_from_civil(year, month, day);
    let whole = s.floor();
    Some(LocalInstant {
        whole_s: days * 86400 + h * 3600 + m * 60 + whole as i64,
        frac_s: (s - whole) + micro * 1e-6,
    })
}

/// Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's algorithm).
fn days_from_civil(y: i64, m: i64, d: i64) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (m + 9) % 12;
    let doy = (153 * mp + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

#[cfg(test)]
mod tests;
