//! Photron's camera information header, in either of its two forms:
//!
//! - **`.cihx`** (Photron FASTCAM Viewer 4 and later): a binary preamble
//!   (`!!! This file can not be edited. !!!`, NUL padding, a `CIHX` block),
//!   then an XML document from `<?xml` on, root `<cih>`. Values read:
//!   `imageDataInfo/resolution/{width,height}`,
//!   `imageDataInfo/colorInfo/{type,bit}`,
//!   `imageDataInfo/effectiveBit/{depth,side}`,
//!   `frameInfo/{totalFrame,startFrame,recordedFrame,skipFrame}`,
//!   `recordInfo/{recordRate,shutterSpeed,shutterSpeedNsec}`,
//!   `imageFileInfo/fileFormat`, `deviceInfo/deviceName`,
//!   `plugin/geometry/{flipH,flipV,rotate}` (the viewer's display settings).
//! - **`.cih`** (older software): text lines `Key : Value` — `Record
//!   Rate(fps)`, `Shutter Speed(s)` (`1/50000` or a decimal), `Total Frame`,
//!   `Start Frame`, `Image Width`, `Image Height`, `Color Type`, `Color
//!   Bit`, `EffectiveBit Depth`, `EffectiveBit Side`, `File Format`, `Camera
//!   Type`, `Original Total Frame`, `Skip Frame`.
//!
//! The XML ends at `</cih>`: real `.cihx` files carry binary bytes after it.
//! [`parse`] tells them apart by content (an XML start `<?xml` or `<cih`),
//! not by the file's name. It works on bytes in memory, bounded by their
//! length: the `photron_cih` fuzz target drives it.

use std::collections::HashMap;

use quick_xml::events::Event;
use quick_xml::Reader;

/// Largest header file read (bytes). Photron's are 5–60 kB.
pub const MAX_HEADER_BYTES: u64 = 4 << 20;

/// Deepest XML nesting accepted (Photron's nest 7 deep).
const MAX_DEPTH: usize = 64;

/// Largest frame accepted (pixels); far beyond any Photron sensor.
const MAX_PIXELS: u64 = 1 << 28;

/// Which end of a sample holds its significant bits (`effectiveBit/side`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BitSide {
    /// Values `0 … 2^depth − 1` as stored (Photron's usual).
    #[default]
    Lower,
    /// The significant bits are the sample's top ones: shifted down on reading.
    Higher,
}

/// Which form the header had.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CihForm {
    /// `.cihx`: XML after a binary preamble.
    Xml,
    /// `.cih`: `Key : Value` text lines.
    Text,
}

/// What dropscope takes from a Photron header.
#[derive(Debug, Clone, PartialEq)]
pub struct Cih {
    /// Which form the header had (`.cihx` XML or `.cih` text).
    pub form: CihForm,
    /// Frame width, px.
    pub width: u32,
    /// Frame height, px.
    pub height: u32,
    /// Frames saved in the MRAW.
    pub total_frames: u64,
    /// Photron's number of the first saved frame (negative before the trigger).
    pub start_frame: i64,
    /// Frames recorded in the camera's memory, when said.
    pub recorded_frames: Option<u64>,
    /// One frame saved of every `skip_frame` recorded (1: all).
    pub skip_frame: u32,
    /// Recording rate, frames per second (before any skip).
    pub record_rate_fps: f64,
    /// Exposure of one frame, seconds (`shutterSpeedNsec`, else `1/shutterSpeed`).
    pub exposure_s: Option<f64>,
    /// Bits a sample occupies in the MRAW: 8, 12 (packed) or 16.
    pub container_bits: u32,
    /// Significant bits of a sample (`effectiveBit/depth`; the container's when absent).
    pub effective_bits: u32,
    /// Which end of a sample holds its significant bits.
    pub side: BitSide,
    /// `colorInfo/type` or `Color Type` as written (`Mono`, `Raw`, `Color` …).
    pub colour_type: Option<String>,
    /// `deviceInfo/deviceName` or `Camera Type`.
    pub camera: Option<String>,
    /// The viewer's display flips and rotation (degrees), recorded, not applied to storage.
    pub flip_h: bool,
    /// The viewer flips the picture upside down (recorded, not applied to storage).
    pub flip_v: bool,
    /// The viewer's rotation, degrees (recorded, not applied to storage).
    pub rotate_deg: f64,
}

impl Cih {
    /// Bytes of one frame in the MRAW.
    pub fn frame_bytes(&self) -> u64 {
        (u64::from(self.width) * u64::from(self.height) * u64::from(self.container_bits))
            .div_ceil(8)
    }

    /// Spacing of the saved frames, frames per second.
    pub fn saved_fps(&self) -> f64 {
        self.record_rate_fps / f64::from(self.skip_frame.max(1))
    }

    /// How the samples are stored, for `inspect`.
    pub fn describe_storage(&self) -> String {
        let how = match self.container_bits {
            8 => "8-bit".to_string(),
            12 => "12-bit packed (2 samples in 3 bytes, high nibble first)".to_string(),
            _ => "16-bit little-endian".to_string(),
        };
        let side = match self.side {
            BitSide::Higher if self.effective_bits < self.container_bits => ", high-aligned",
            _ => "",
        };
        format!(
            "{how}, {} significant bits{side}, rows top-down",
            self.effective_bits
        )
    }
}

/// Parse a header's bytes, XML or text form (see the module doc). Errors say
/// what is missing or wrong, naming the field as the file writes it; an
/// `unsupported: ` prefix marks a recording dropscope does not read.
pub fn parse(bytes: &[u8]) -> Result<Cih, String> {
    let xml_at = find(bytes, b"<?xml").or_else(|| find(bytes, b"<cih"));
    match xml_at {
        Some(at) => from_fields(CihForm::Xml, &xml_fields(&bytes[at..])?),
        None => from_fields(CihForm::Text, &text_fields(bytes)?),
    }
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

/// The names a value is looked up by: (XML path under `<cih>`, text key).
#[derive(Clone, Copy)]
struct Field {
    xml: &'static [&'static str],
    text: &'static str,
}

const WIDTH: Field = Field {
    xml: &[
        "imageDataInfo/resolution/width",
        "imageFileInfo/resolution/width",
    ],
    text: "image width",
};
const HEIGHT: Field = Field {
    xml: &[
        "imageDataInfo/resolution/height",
        "imageFileInfo/resolution/height",
    ],
    text: "image height",
};
const COLOUR_TYPE: Field = Field {
    xml: &["imageDataInfo/colorInfo/type"],
    text: "color type",
};
const COLOUR_BIT: Field = Field {
    xml: &["imageDataInfo/colorInfo/bit"],
    text: "color bit",
};
const EFFECTIVE_DEPTH: Field = Field {
    xml: &["imageDataInfo/effectiveBit/depth"],
    text: "effectivebit depth",
};
const EFFECTIVE_SIDE: Field = Field {
    xml: &["imageDataInfo/effectiveBit/side"],
    text: "effectivebit side",
};
const TOTAL_FRAME: Field = Field {
    xml: &["frameInfo/totalFrame"],
    text: "total frame",
};
const START_FRAME: Field = Field {
    xml: &["frameInfo/startFrame"],
    text: "start frame",
};
const RECORDED_FRAME: Field = Field {
    xml: &["frameInfo/recordedFrame"],
    text: "original total frame",
};
const SKIP_FRAME: Field = Field {
    xml: &["frameInfo/skipFrame"],
    text: "skip frame",
};
const RECORD_RATE: Field = Field {
    xml: &["recordInfo/recordRate"],
    text: "record rate(fps)",
};
const SHUTTER: Field = Field {
    xml: &["recordInfo/shutterSpeed"],
    text: "shutter speed(s)",
};
const SHUTTER_NS: Field = Field {
    xml: &["recordInfo/shutterSpeedNsec"],
    text: "shutter speed(ns)",
};
const FILE_FORMAT: Field = Field {
    xml: &["imageFileInfo/fileFormat"],
    text: "file format",
};
const CAMERA: Field = Field {
    xml: &["deviceInfo/deviceName"],
    text: "camera type",
};
const FLIP_H: Field = Field {
    xml: &["plugin/geometry/flipH"],
    text: "",
};
const FLIP_V: Field = Field {
    xml: &["plugin/geometry/flipV"],
    text: "",
};
const ROTATE: Field = Field {
    xml: &["plugin/geometry/rotate"],
    text: "",
};

const FIELDS: [Field; 18] = [
    WIDTH,
    HEIGHT,
    COLOUR_TYPE,
    COLOUR_BIT,
    EFFECTIVE_DEPTH,
    EFFECTIVE_SIDE,
    TOTAL_FRAME,
    START_FRAME,
    RECORDED_FRAME,
    SKIP_FRAME,
    RECORD_RATE,
    SHUTTER,
    SHUTTER_NS,
    FILE_FORMAT,
    CAMERA,
    FLIP_H,
    FLIP_V,
    ROTATE,
];

/// Values found, keyed by the field's first XML path (XML) or text key.
struct Found {
    form: CihForm,
    values: HashMap<&'static str, String>,
}

impl Found {
    fn get(&self, f: Field) -> Option<&str> {
        let key = match self.form {
            CihForm::Xml => f.xml.iter().find(|p| self.values.contains_key(*p))?,
            CihForm::Text => f.text,
        };
        self.values
            .get(key)
            .map(|s| s.trim())
            .filter(|s| !s.is_empty())
    }

    /// How the file names `f`, for messages.
    fn name(&self, f: Field) -> String {
        match self.form {
            CihForm::Xml => format!("<{}>", f.xml[0].rsplit('/').next().unwrap_or(f.xml[0])),
            CihForm::Text => format!("`{}`", title(f.text)),
        }
    }
}

/// A text key as Photron writes it (`record rate(fps)` → `Record Rate(fps)`).
fn title(key: &str) -> String {
    match key {
        "effectivebit depth" => "EffectiveBit Depth".into(),
        "effectivebit side" => "EffectiveBit Side".into(),
        _ => key
            .split(' ')
            .map(|w| {
                let mut c = w.chars();
                c.next()
                    .map(|f| f.to_uppercase().chain(c).collect::<String>())
                    .unwrap_or_default()
            })
            .collect::<Vec<_>>()
            .join(" "),
    }
}

/// The values of [`FIELDS`] in an XML document (bytes from `<?xml` or `<cih` on).
fn xml_fields(bytes: &[u8]) -> Result<Found, String> {
    let mut reader = Reader::from_reader(bytes);
    let mut path: Vec<String> = Vec::new();
    let mut values: HashMap<&'static str, String> = HashMap::new();
    let mut root_seen = false;
    let mut buf = Vec::new();
    loop {
        let event = reader.read_event_into(&mut buf).map_err(|e| {
            format!(
                "the header's XML is not valid at byte {}: {e}",
                reader.error_position()
            )
        })?;
        match event {
            Event::Start(e) => {
                let name = e.local_name().as_ref().to_string();
                if path.is_empty() {
                    if root_seen || name != "cih" {
                        return Err(format!(
                            "the header's XML has root <{name}>, not <cih>: not a Photron header"
                        ));
                    }
                    root_seen = true;
                }
                path.push(name);
                if path.len() > MAX_DEPTH {
                    return Err(format!(
                        "the header's XML nests deeper than {MAX_DEPTH} elements: not a Photron header"
                    ));
                }
            }
            Event::End(_) => {
                path.pop();
                if path.is_empty() {
                    // The root's end: what follows (binary padding in
                    // real .cihx files) is not the header's.
                    break;
                }
            }
            Event::Empty(e) if path.is_empty() => {
                let name = e.local_name().as_ref().to_string();
                return Err(format!(
                    "the header's XML has root <{name}>, not <cih>: not a Photron header"
                ));
            }
            Event::Text(t) if path.len() > 1 => {
                let joined = path[1..].join("/");
                if let Some(key) = FIELDS
                    .iter()
                    .flat_map(|f| f.xml.iter())
                    .find(|p| **p == joined)
                {
                    if !values.contains_key(key) {
                        values.insert(key, t.xml10_content().into_owned());
                    }
                }
            }
            Event::Eof => {
                if let Some(open) = path.last() {
                    return Err(format!(
                        "the header's XML ends inside <{open}>: truncated or corrupt"
                    ));
                }
                break;
            }
            _ => {}
        }
        buf.clear();
    }
    if !root_seen {
        return Err("the header holds no <cih> element: not a Photron header".into());
    }
    Ok(Found {
        form: CihForm::Xml,
        values,
    })
}

/// The values of [`FIELDS`] in `Key : Value` lines (keys compared without
/// case; the first occurrence counts).
fn text_fields(bytes: &[u8]) -> Result<Found, String> {
    let text = String::from_utf8_lossy(bytes);
    let mut values: HashMap<&'static str, String> = HashMap::new();
    for line in text.lines() {
        let Some((key, value)) = line.split_once(':') else {
            continue;
        };
        let key = key.trim().to_ascii_lowercase();
        if let Some(f) = FIELDS.iter().find(|f| !f.text.is_empty() && f.text == key) {
            values
                .entry(f.text)
                .or_insert_with(|| value.trim().to_string());
        }
    }
    if values.is_empty() {
        return Err(
            "neither a .cihx (no <?xml … <cih>) nor a .cih (no `Key : Value` lines such as \
             `Record Rate(fps) : 30000`): not a Photron header"
                .into(),
        );
    }
    Ok(Found {
        form: CihForm::Text,
        values,
    })
}

fn number<T: std::str::FromStr>(found: &Found, f: Field) -> Result<Option<T>, String> {
    found
        .get(f)
        .map(|s| {
            s.parse::<T>()
                .map_err(|_| format!("the header's {} {s:?} is not a number", found.name(f)))
        })
        .transpose()
}

fn required<T: std::str::FromStr>(found: &Found, f: Field) -> Result<T, String> {
    number(found, f)?.ok_or_else(|| format!("the header has no {}", found.name(f)))
}

/// `1/50000`, `0.00002` or `2e-5` seconds.
fn shutter_s(text: &str) -> Option<f64> {
    let v = match text.split_once('/') {
        Some((a, b)) => a.trim().parse::<f64>().ok()? / b.trim().parse::<f64>().ok()?,
        None => text.trim().parse::<f64>().ok()?,
    };
    (v.is_finite() && v > 0.0).then_some(v)
}

/// The exposure (s): the header's shutter in ns, else its shutter (the XML
/// writes the denominator: 50000 for 1/50000 s), else none; an error when
/// it is not an exposure.
fn exposure_of(form: CihForm, found: &Found) -> Result<Option<f64>, String> {
    Ok(match number::<f64>(found, SHUTTER_NS)? {
        Some(ns) if ns > 0.0 => Some(ns * 1e-9),
        _ => match found.get(SHUTTER) {
            None => None,
            Some(s) => {
                // The XML writes the denominator (50000 for 1/50000 s).
                let v = match (form, s.contains('/')) {
                    (CihForm::Xml, false) => s.trim().parse::<f64>().ok().map(|d| 1.0 / d),
                    _ => shutter_s(s),
                };
                match v {
                    Some(v) if v.is_finite() && v > 0.0 => Some(v),
                    _ => {
                        return Err(format!(
                            "the header's {} {s:?} is not an exposure",
                            found.name(SHUTTER)
                        ))
                    }
                }
            }
        },
    })
}

fn from_fields(form: CihForm, found: &Found) -> Result<Cih, String> {
    if let Some(ff) = found.get(FILE_FORMAT) {
        if !ff.eq_ignore_ascii_case("mraw") {
            return Err(format!(
                "unsupported: the recording was saved as {ff} ({} {ff}), not MRAW; \
                 dropscope reads Photron MRAW files with their .cihx/.cih, and folders \
                 of numbered TIFF/PNG/BMP/JPEG frames",
                found.name(FILE_FORMAT)
            ));
        }
    }
    let width: u32 = required(found, WIDTH)?;
    let height: u32 = required(found, HEIGHT)?;
    if width == 0 || height == 0 || u64::from(width) * u64::from(height) > MAX_PIXELS {
        return Err(format!(
            "the header's frame size {width}×{height} is impossible: corrupt header"
        ));
    }
    let colour_type = found.get(COLOUR_TYPE).map(str::to_string);
    let container_bits: u32 = required(found, COLOUR_BIT)?;
    let colour = colour_type.as_deref().is_some_and(|t| {
        let t = t.to_ascii_lowercase();
        t.starts_with("col") || t == "rgb" || t == "bayer"
    });
    if colour || container_bits > 16 {
        return Err(format!(
            "unsupported: a colour Photron recording ({} {}, {} {container_bits}); \
             dropscope reads monochrome MRAW (8-bit, 12-bit packed, 16-bit)",
            found.name(COLOUR_TYPE),
            colour_type.as_deref().unwrap_or("?"),
            found.name(COLOUR_BIT)
        ));
    }
    if !matches!(container_bits, 8 | 12 | 16) {
        return Err(format!(
            "unsupported: {} {container_bits} (dropscope reads 8-bit, 12-bit packed and \
             16-bit MRAW)",
            found.name(COLOUR_BIT)
        ));
    }
    let effective_bits: u32 = number(found, EFFECTIVE_DEPTH)?.unwrap_or(container_bits);
    if effective_bits == 0 || effective_bits > container_bits {
        return Err(format!(
            "the header's {} {effective_bits} does not fit in {} {container_bits}: corrupt header",
            found.name(EFFECTIVE_DEPTH),
            found.name(COLOUR_BIT)
        ));
    }
    let side = match found.get(EFFECTIVE_SIDE) {
        None => BitSide::Lower,
        Some(s) if s.eq_ignore_ascii_case("lower") => BitSide::Lower,
        Some(s) if s.eq_ignore_ascii_case("higher") => BitSide::Higher,
        Some(s) => {
            return Err(format!(
                "the header's {} is {s:?}, neither Lower nor Higher",
                found.name(EFFECTIVE_SIDE)
            ))
        }
    };
    let total_frames: u64 = required(found, TOTAL_FRAME)?;
    if total_frames == 0 {
        return Err(format!(
            "the header's {} is 0: the recording holds no frame",
            found.name(TOTAL_FRAME)
        ));
    }
    let start_frame: i64 = number(found, START_FRAME)?.unwrap_or(0);
    let recorded_frames: Option<u64> = number(found, RECORDED_FRAME)?;
    let skip_frame: u32 = number(found, SKIP_FRAME)?.unwrap_or(1);
    if skip_frame == 0 {
        return Err(format!(
            "the header's {} is 0: corrupt header",
            found.name(SKIP_FRAME)
        ));
    }
    let record_rate_fps: f64 = required(found, RECORD_RATE)?;
    let exposure_s = exposure_of(form, found)?;
    let flag = |f: Field| {
        found
            .get(f)
            .is_some_and(|s| s.eq_ignore_ascii_case("true") || s == "1")
    };
    let rotate_deg = number::<f64>(found, ROTATE)?.unwrap_or(0.0);
    Ok(Cih {
        form,
        width,
        height,
        total_frames,
        start_frame,
        recorded_frames,
        skip_frame,
        record_rate_fps,
        exposure_s,
        container_bits,
        effective_bits,
        side,
        colour_type,
        camera: found.get(CAMERA).map(str::to_string),
        flip_h: flag(FLIP_H),
        flip_v: flag(FLIP_V),
        rotate_deg: if rotate_deg.is_finite() {
            rotate_deg
        } else {
            0.0
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = "#Camera Information Header\r\n\
        Date : 2016/5/4\r\n\
        Camera Type : FASTCAM SA5 model 7\r\n\
        Record Rate(fps) : 100000\r\n\
        Shutter Speed(s) : 1/200000\r\n\
        Total Frame : 40\r\n\
        Start Frame : -20\r\n\
        Image Width : 128\r\n\
        Image Height : 64\r\n\
        Color Type : Mono\r\n\
        Color Bit : 16\r\n\
        File Format : MRaw\r\n\
        EffectiveBit Depth : 12\r\n\
        EffectiveBit Side : Higher\r\n\
        END\r\n";

    #[test]
    fn a_text_header_gives_its_values() {
        let c = parse(TEXT.as_bytes()).unwrap();
        assert_eq!(c.form, CihForm::Text);
        assert_eq!((c.width, c.height, c.total_frames), (128, 64, 40));
        assert_eq!(c.start_frame, -20);
        assert_eq!(c.record_rate_fps, 100_000.0);
        assert_eq!(c.exposure_s, Some(5e-6));
        assert_eq!((c.container_bits, c.effective_bits), (16, 12));
        assert_eq!(c.side, BitSide::Higher);
        assert_eq!(c.camera.as_deref(), Some("FASTCAM SA5 model 7"));
        assert_eq!(c.frame_bytes(), 128 * 64 * 2);
    }

    #[test]
    fn what_is_missing_or_wrong_is_named_as_the_file_writes_it() {
        let no_rate = TEXT.replace("Record Rate(fps) : 100000\r\n", "");
        assert_eq!(
            parse(no_rate.as_bytes()).unwrap_err(),
            "the header has no `Record Rate(fps)`"
        );
        let tiff = TEXT.replace("MRaw", "TIFF");
        let e = parse(tiff.as_bytes()).unwrap_err();
        assert!(
            e.starts_with("unsupported: the recording was saved as TIFF"),
            "{e}"
        );
        let colour = TEXT
            .replace("Mono", "Color")
            .replace("Bit : 16", "Bit : 24");
        let e = parse(colour.as_bytes()).unwrap_err();
        assert!(e.contains("a colour Photron recording"), "{e}");
        let e = parse(b"<?xml version=\"1.0\"?><chd><a>1</a></chd>").unwrap_err();
        assert!(e.contains("root <chd>, not <cih>"), "{e}");
        let e = parse(b"\x00\x01\x02 random").unwrap_err();
        assert!(e.contains("not a Photron header"), "{e}");
        let deep = format!("<?xml?><cih>{}", "<a>".repeat(100));
        assert!(parse(deep.as_bytes()).unwrap_err().contains("deeper"));
    }
}
