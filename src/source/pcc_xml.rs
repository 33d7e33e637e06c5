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

/// Parse a PCC XML document. Errors say what is wrong (not XML, wrong root,
/// a value that is not a number); missing optional elements are `None`.
pub fn parse(text: &str) -> Result<PccXml, String> {
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
    let fps = match num::<f64>(text_of(setup, "FrameRateDouble"), "FrameRateDouble")? {
        Some(f) => Some(f),
        None => num::<f64>(text_of(setup, "FrameRate"), "FrameRate")?,
    };
    let exposure_s = match num::<f64>(text_of(setup, "ShutterNs"), "ShutterNs")? {
        Some(ns) => Some(ns * 1e-9),
        None => num::<f64>(text_of(setup, "Shutter"), "Shutter")?.map(|us| us * 1e-6),
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
    fn wrong_root_and_bad_numbers_are_errors() {
        assert!(parse("<cine/>").unwrap_err().contains("<chd>"));
        let e =
            parse("<chd><CameraSetup><RealBPP>twelve</RealBPP></CameraSetup></chd>").unwrap_err();
        assert!(e.contains("RealBPP"), "{e}");
    }
}
