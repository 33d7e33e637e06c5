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

/// What dropscope takes from a PCC XML. Fields are `None` when absent.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PccXml {
    /// `CineFileHeader/FirstImageNo`: image number of the first exported image.
    pub first_image_no: Option<i64>,
    /// `CineFileHeader/ImageCount`: number of exported images.
    pub image_count: Option<u64>,
    pub width: Option<u32>,
    pub height: Option<u32>,
    /// `BitmapInfoHeader/biBitCount` of the exported images.
    pub bit_count: Option<u32>,
    /// `CameraSetup/FrameRateDouble`, else `CameraSetup/FrameRate`, frames/s.
    pub fps: Option<f64>,
    /// `CameraSetup/ShutterNs` (ns), else `Shutter` (µs), in seconds.
    pub exposure_s: Option<f64>,
    pub real_bpp: Option<u8>,
    pub black_level: Option<i64>,
    pub white_level: Option<i64>,
    pub flip_h: Option<bool>,
    pub flip_v: Option<bool>,
    /// `(image number, seconds after the trigger)` from `TIMEBLOCK`, in file order.
    pub times: Vec<(i64, f64)>,
    /// `(image number, exposure seconds)` from `EXPOSUREBLOCK`.
    pub exposures: Vec<(i64, f64)>,
}

/// Largest side file read, in bytes: a TIMEBLOCK and an EXPOSUREBLOCK for
/// about 500 000 frames (PCC writes ~120 bytes a frame).
pub const MAX_XML_BYTES: usize = 64 << 20;

/// Deepest element nesting accepted. PCC's files nest 4 deep; the parser
/// builds its tree recursively, and 100 000 levels overflow a thread's stack.
pub const MAX_XML_DEPTH: usize = 64;

/// Parse a PCC XML document. Errors say what is wrong (too large or too
/// deeply nested, checked before parsing; not XML, wrong root, a value that
/// is not a number or not a possible frame rate or exposure); missing
/// optional elements are `None`.
pub fn parse(text: &str) -> Result<PccXml, String> {
    if text.len() > MAX_XML_BYTES {
        return Err(format!(
            "{} bytes: larger than any PCC side file ({} MiB at most)",
            text.len(),
            MAX_XML_BYTES >> 20
        ));
    }
    if let Some(line) = too_deep(text, MAX_XML_DEPTH) {
        return Err(format!(
            "elements nested more than {MAX_XML_DEPTH} deep (at line {line}): not a PCC side file"
        ));
    }
    let doc = roxmltree::Document::parse(text).map_err(|e| format!("not valid XML: {e}"))?;
    let root = doc.root_element();
    if root.tag_name().name() != "chd" {
        return Err(format!(
            "root element is <{}>, not PCC's <chd>",
            root.tag_name().name()
        ));
    }
    let header = child(root, "CineFileHeader");
    let bitmap = child(root, "BitmapInfoHeader");
    let setup = child(root, "CameraSetup");
    let text_of = |parent: Option<roxmltree::Node<'_, '_>>, name: &str| -> Option<String> {
        parent
            .and_then(|p| child(p, name))
            .map(|n| n.text().unwrap_or("").trim().to_string())
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
        match num::<f64>(text_of(setup, name), name)? {
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
    let trigger = header.and_then(|h| child(h, "TriggerTime")).map(|t| {
        let d = child(t, "Date").and_then(|n| n.text()).unwrap_or("");
        let tm = child(t, "Time").and_then(|n| n.text()).unwrap_or("");
        local_seconds(d, tm)
            .ok_or_else(|| format!("TriggerTime {d:?} {tm:?} is not a PCC date/time"))
    });
    let trigger = trigger.transpose()?;
    let mut instants = Vec::new();
    if let Some(block) = child(root, "TIMEBLOCK") {
        // Date and Time elements come in pairs sharing a frame attribute.
        let mut date_of_frame: Vec<(i64, &str)> = Vec::new();
        for n in block.children().filter(|n| n.is_element()) {
            let frame = frame_attr(n)?;
            let value = n.text().unwrap_or("");
            match n.tag_name().name() {
                "Date" => date_of_frame.push((frame, value)),
                "Time" => {
                    let date = date_of_frame
                        .iter()
                        .rev()
                        .find(|(f, _)| *f == frame)
                        .map(|(_, d)| *d)
                        .ok_or_else(|| format!("TIMEBLOCK Time frame={frame} has no Date"))?;
                    let t = local_seconds(date, value).ok_or_else(|| {
                        format!(
                            "TIMEBLOCK frame={frame}: {date:?} {value:?} is not a PCC date/time"
                        )
                    })?;
                    instants.push((frame, t));
                }
                _ => {}
            }
        }
    }
    // Relative to the trigger; without one, to the first listed frame.
    let times = match trigger.or(instants.first().map(|t| t.1)) {
        Some(origin) => instants
            .iter()
            .map(|(f, t)| (*f, t.since(origin)))
            .collect(),
        None => Vec::new(),
    };
    let mut exposures = Vec::new();
    if let Some(block) = child(root, "EXPOSUREBLOCK") {
        for n in block
            .children()
            .filter(|n| n.is_element() && n.tag_name().name() == "Exp")
        {
            let frame = frame_attr(n)?;
            let us: f64 = n
                .text()
                .unwrap_or("")
                .trim()
                .parse()
                .map_err(|_| format!("EXPOSUREBLOCK frame={frame} is not a number"))?;
            exposures.push((frame, us * 1e-6));
        }
    }
    Ok(PccXml {
        first_image_no: num(text_of(header, "FirstImageNo"), "FirstImageNo")?,
        image_count: num(text_of(header, "ImageCount"), "ImageCount")?,
        width: num(text_of(bitmap, "biWidth"), "biWidth")?,
        height: num(text_of(bitmap, "biHeight"), "biHeight")?,
        bit_count: num(text_of(bitmap, "biBitCount"), "biBitCount")?,
        fps,
        exposure_s,
        real_bpp: num(text_of(setup, "RealBPP"), "RealBPP")?,
        black_level: num(text_of(setup, "BlackLevel"), "BlackLevel")?,
        white_level: num(text_of(setup, "WhiteLevel"), "WhiteLevel")?,
        flip_h: boolean(text_of(setup, "bFlipH")),
        flip_v: boolean(text_of(setup, "bFlipV")),
        times,
        exposures,
    })
}

/// The line where elements first nest deeper than `limit`, if they do. A
/// scan over the text that knows tags, quoted attribute values, comments,
/// CDATA, processing instructions and declarations; malformed text is left
/// for the parser to reject, since the scan only has to bound what it
/// would build.
fn too_deep(text: &str, limit: usize) -> Option<usize> {
    let b = text.as_bytes();
    let line = |i: usize| 1 + b[..i].iter().filter(|&&c| c == b'\n').count();
    let skip_past = |from: usize, end: &[u8]| -> usize {
        b[from..]
            .windows(end.len())
            .position(|w| w == end)
            .map_or(b.len(), |k| from + k + end.len())
    };
    let mut depth = 0usize;
    let mut i = 0;
    while i < b.len() {
        if b[i] != b'<' {
            i += 1;
            continue;
        }
        let rest = &b[i..];
        if rest.starts_with(b"<!--") {
            i = skip_past(i + 4, b"-->");
        } else if rest.starts_with(b"<![CDATA[") {
            i = skip_past(i + 9, b"]]>");
        } else if rest.starts_with(b"<?") {
            i = skip_past(i + 2, b"?>");
        } else if rest.starts_with(b"<!") {
            i = skip_past(i + 2, b">");
        } else {
            // A tag: find its end outside quoted values.
            let closing = rest.get(1) == Some(&b'/');
            let mut j = i + 1;
            let mut quote = None;
            while j < b.len() {
                match (quote, b[j]) {
                    (None, b'"' | b'\'') => quote = Some(b[j]),
                    (Some(q), c) if c == q => quote = None,
                    (None, b'>') => break,
                    _ => {}
                }
                j += 1;
            }
            let empty = j > i + 1 && b.get(j - 1) == Some(&b'/');
            if closing {
                depth = depth.saturating_sub(1);
            } else if !empty {
                depth += 1;
                if depth > limit {
                    return Some(line(i));
                }
            }
            i = j + 1;
        }
    }
    None
}

fn child<'a, 'i>(parent: roxmltree::Node<'a, 'i>, name: &str) -> Option<roxmltree::Node<'a, 'i>> {
    parent
        .children()
        .find(|n| n.is_element() && n.tag_name().name() == name)
}

fn frame_attr(n: roxmltree::Node<'_, '_>) -> Result<i64, String> {
    let a = n.attribute("frame").ok_or_else(|| {
        format!(
            "<{}> in a block has no frame attribute",
            n.tag_name().name()
        )
    })?;
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
mod tests {
    use super::*;

    #[test]
    fn civil_days_match_known_dates() {
        assert_eq!(days_from_civil(1970, 1, 1), 0);
        // 2019-08-24 is day 18132 since the epoch (1566604800 s / 86400).
        assert_eq!(days_from_civil(2019, 8, 24), 18132);
        assert_eq!(days_from_civil(2000, 3, 1), 11017);
    }

    #[test]
    fn pcc_time_has_microseconds_after_the_milliseconds() {
        let t = local_seconds("Sat Aug 24 2019", "14:53:32.328 240.68").unwrap();
        assert_eq!(t.whole_s, 18132 * 86400 + 14 * 3600 + 53 * 60 + 32);
        assert!((t.frac_s - (0.328 + 240.68e-6)).abs() < 1e-9, "{t:?}");
        assert!(local_seconds("Sat Aug 24 2019", "25:00:00.000 0.00").is_none());
        assert!(local_seconds("Sat Foo 24 2019", "14:53:32.328 240.68").is_none());
    }

    #[test]
    fn time_under_the_trigger_is_not_a_frame_time() {
        let xml = r#"<?xml version="1.0"?><chd><CineFileHeader><FirstImageNo>-2</FirstImageNo>
            <TriggerTime><Date>Thu Jan 01 1970</Date><Time>00:00:01.000 000.00</Time></TriggerTime>
            </CineFileHeader><CameraSetup><FrameRate>1000</FrameRate><Shutter>50</Shutter></CameraSetup>
            <TIMEBLOCK><Date frame="-2">Thu Jan 01 1970</Date><Time frame="-2">00:00:00.998 000.00</Time>
            <Date frame="-1">Thu Jan 01 1970</Date><Time frame="-1">00:00:00.999 000.00 E</Time></TIMEBLOCK></chd>"#;
        let x = parse(xml).unwrap();
        assert_eq!(x.fps, Some(1000.0));
        assert!((x.exposure_s.unwrap() - 50e-6).abs() < 1e-15);
        assert_eq!(x.times.len(), 2);
        assert_eq!(x.times[0].0, -2);
        assert!((x.times[0].1 + 0.002).abs() < 1e-9);
        assert!((x.times[1].1 + 0.001).abs() < 1e-9);
    }

    #[test]
    fn deep_nesting_is_refused_before_parsing() {
        // 100 000 levels overflowed the stack in the parser (issue 14).
        let deep = format!(
            "<chd>{}{}</chd>",
            "<a>".repeat(100_000),
            "</a>".repeat(100_000)
        );
        let e = parse(&deep).unwrap_err();
        assert!(e.contains("nested more than 64 deep"), "{e}");
        // Comments, CDATA, quoted `>` and empty elements do not nest.
        let flat = format!(
            "<?xml version=\"1.0\"?><chd><!-- <a><a> -->{}<x a=\"b>\" b='>'/><![CDATA[<c><c>]]>\
             <CameraSetup><FrameRate>10</FrameRate></CameraSetup></chd>",
            "<e/>".repeat(100)
        );
        assert_eq!(too_deep(&flat, 3), None);
        assert_eq!(parse(&flat).unwrap().fps, Some(10.0));
        assert_eq!(too_deep("<a>\n<b>\n<c>", 2), Some(3));
        let big = format!("<chd>{}</chd>", " ".repeat(MAX_XML_BYTES));
        assert!(parse(&big)
            .unwrap_err()
            .contains("larger than any PCC side file"));
    }

    #[test]
    fn impossible_frame_rates_and_exposures_are_errors() {
        for (elem, value) in [
            ("FrameRateDouble", "NaN"),
            ("FrameRateDouble", "0"),
            ("FrameRate", "-10000"),
            ("ShutterNs", "inf"),
            ("Shutter", "-5"),
        ] {
            let xml = format!("<chd><CameraSetup><{elem}>{value}</{elem}></CameraSetup></chd>");
            let e = parse(&xml).unwrap_err();
            assert!(
                e.contains(elem) && e.contains("finite number above 0"),
                "{e}"
            );
        }
    }

    #[test]
    fn wrong_root_and_bad_numbers_are_errors() {
        assert!(parse("<cine/>").unwrap_err().contains("<chd>"));
        let e =
            parse("<chd><CameraSetup><RealBPP>twelve</RealBPP></CameraSetup></chd>").unwrap_err();
        assert!(e.contains("RealBPP"), "{e}");
    }
}
