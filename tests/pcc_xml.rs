//! The PCC side file read as a stream (`pcc_xml::read`) against a tree
//! reader kept here as the reference: the same values, bit for bit, on
//! every real and rendered side file, cut anywhere, split across buffers
//! of any size, and on what a stream could read differently from a tree
//! (entities, CDATA, comments, elements out of PCC's order, repeated
//! elements).

use std::io::{BufReader, Read};
use std::path::Path;

use dropscope::render::export::{pcc_xml as rendered_xml, PccHeader};
use dropscope::source::pcc_xml::{self, local_seconds, PccXml};

/// Every value of `x`, floats as their bits.
fn bits(x: &PccXml) -> String {
    let pairs = |v: &[(i64, f64)]| -> Vec<(i64, u64)> {
        v.iter().map(|(n, t)| (*n, t.to_bits())).collect()
    };
    format!(
        "{:?} {:?} {:?} {:?} {:?} {:?} {:?} {:?} {:?} {:?} {:?} {:?} {:?} {:?}",
        x.first_image_no,
        x.image_count,
        (x.width, x.height, x.bit_count),
        x.fps.map(f64::to_bits),
        x.exposure_s.map(f64::to_bits),
        x.real_bpp,
        x.black_level,
        x.white_level,
        x.flip_h,
        x.flip_v,
        x.times.len(),
        x.exposures.len(),
        pairs(&x.times),
        pairs(&x.exposures),
    )
}

/// The stream reads `text` as the tree reader did: the same values, or
/// both refuse it for the same reason. Returns the stream's answer.
fn as_the_tree(text: &str, what: &str) -> Result<PccXml, String> {
    let want = reference::parse(text);
    let got = pcc_xml::parse(text);
    match (&want, &got) {
        (Ok(w), Ok(g)) => assert!(bits(w) == bits(g), "{what}: the values differ"),
        // Not XML in both (the places are told differently), else the
        // same message.
        (Err(w), Err(g)) if w.starts_with("not valid XML") => {
            assert!(g.starts_with("not valid XML"), "{what}: {w} / {g}")
        }
        (Err(w), Err(g)) => assert_eq!(w, g, "{what}"),
        _ => panic!(
            "{what}: the tree reader {:?}, the stream {:?}",
            want.as_ref().err(),
            got.as_ref().err()
        ),
    }
    got
}

fn real_and_rendered() -> Vec<(String, String)> {
    let mut files: Vec<(String, String)> = ["12bpp", "8bpp", "cam_1", "packed_10"]
        .iter()
        .map(|n| {
            let p = crate::phantom_sample(&format!("cinefiles-jl/{n}.xml"));
            (n.to_string(), std::fs::read_to_string(p).unwrap())
        })
        .collect();
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures");
    for run in ["R3mm_H1.5cm_01", "R4.5mm_H12cm_01", "R7mm_H50cm_01"] {
        let p = fixtures.join(run).join(format!("{run}.xml"));
        files.push((run.to_string(), std::fs::read_to_string(p).unwrap()));
    }
    files
}

#[test]
fn real_and_rendered_side_files_read_as_the_tree_reader_read_them() {
    need!(crate::Need::PhantomSamples);
    let mut files = real_and_rendered();
    // A long export as `dropscope render` writes it: 50 000 frames.
    files.push((
        "rendered 50 000 frames".into(),
        rendered_xml(&PccHeader {
            description: "a & b <c>".into(),
            first_image_no: -1000,
            image_count: 50_000,
            width_px: 96,
            height_px: 72,
            bit_depth: 12,
            fps: 60_000.0,
            exposure_s: 10e-6,
            trigger_10ns: 1_700_000_000 * 100_000_000 + 12_345_678,
        }),
    ));
    for (name, text) in &files {
        let x = as_the_tree(text, name).unwrap();
        assert!(!x.times.is_empty() && !x.exposures.is_empty(), "{name}");
        // Read through buffers of any size: an element, a value, a
        // reference split between two reads.
        for capacity in [1, 2, 3, 5, 16, 61, 4096] {
            let y = pcc_xml::read(BufReader::with_capacity(capacity, text.as_bytes())).unwrap();
            assert!(bits(&x) == bits(&y), "{name}, {capacity}-byte buffer");
        }
    }
}

/// A file cut short anywhere (a copy that stopped) is refused as the tree
/// reader refused it, as XML that does not close, never read as fewer
/// frames; past the root's end it reads whole.
#[test]
fn a_side_file_cut_anywhere_is_refused_as_not_xml() {
    need!(crate::Need::PhantomSamples);
    for (name, text) in real_and_rendered().iter().take(5) {
        let end = text.rfind("</chd>").unwrap() + "</chd>".len();
        for len in (0..text.len()).filter(|&l| text.is_char_boundary(l)) {
            match as_the_tree(&text[..len], &format!("{name} cut at {len}")) {
                Ok(_) => assert!(len >= end, "{name} cut at {len} read"),
                Err(e) => assert!(e.starts_with("not valid XML"), "{name} cut at {len}: {e}"),
            }
        }
    }
}

#[test]
fn what_a_stream_could_read_differently_reads_as_the_tree() {
    need!(crate::Need::PhantomSamples);
    let real = std::fs::read_to_string(crate::phantom_sample("cinefiles-jl/cam_1.xml")).unwrap();
    let edits = read_alike_edits(&real);
    for (what, text) in &edits {
        assert!(text != &real, "{what}: the edit changed nothing");
        as_the_tree(text, what).unwrap_or_else(|e| panic!("{what}: {e}"));
    }
    let refused = refused_edits(&real);
    for (what, text) in &refused {
        assert!(text != &real, "{what}: the edit changed nothing");
        assert!(as_the_tree(text, what).is_err(), "{what} read");
    }
}

/// Edits of the real side file `real` that a stream could read otherwise
/// than the tree, and that both must read alike.
fn read_alike_edits(real: &str) -> Vec<(&'static str, String)> {
    vec![
        // References and CDATA in values and attributes.
        (
            "character references",
            real.replace(">7500<", ">7&#53;0&#x30;<")
                .replace("frame=\"1\"", "frame=\"&#49;\""),
        ),
        ("an entity", real.replace("</CameraSetup>", "<Description>&amp;&lt;&gt;&quot;&apos;</Description></CameraSetup>")),
        ("CDATA", real.replace(">7500<", "><![CDATA[75]]>0<![CDATA[0]]><")),
        ("CDATA in an Exp", real.replace(">63.853</Exp>", "><![CDATA[63.]]>853</Exp>")),
        // A value runs on across a comment or a processing instruction; an
        // element ends it.
        ("a comment before a value", real.replace(">12</RealBPP>", "><!-- x -->12</RealBPP>")),
        ("a comment inside a value", real.replace(">4064<", ">40<!-- x -->64<")),
        ("a PI inside a value", real.replace(">4064<", ">40<?pi x?>64<")),
        ("an element inside a value", real.replace(">4064<", ">40<b>1</b>64<")),
        ("an empty value", real.replace(">4064<", "><")),
        ("a self-closed value", real.replace("<WhiteLevel>4064</WhiteLevel>", "<WhiteLevel/>")),
        ("spaces around a value", real.replace(">4064<", ">\r\n\t 4064 \r\n<")),
        ("CR LF line ends", real.replace("><", ">\r\n<")),
        ("a byte-order mark", format!("\u{feff}{real}")),
        ("a namespace prefix", real.replace("<chd>", "<p:chd xmlns:p=\"urn:x\">").replace("</chd>", "</p:chd>")),
        // Repeated elements: a value given twice alike, a header repeated
        // with the same values; of the trigger and the blocks, the first counts.
        (
            "a frame rate given twice alike",
            real.replace("<FrameRateDouble>7500</FrameRateDouble>", "<FrameRateDouble>7500</FrameRateDouble><FrameRateDouble> 7500 </FrameRateDouble>"),
        ),
        (
            "two headers",
            real.replace("<CineFileHeader>", "<CineFileHeader><TriggerTime><Date>Mon Jan 01 2001</Date><Time>00:00:00.000 000.00</Time></TriggerTime></CineFileHeader><CineFileHeader>"),
        ),
        ("two trigger dates", real.replace("<TriggerTime><Date>", "<TriggerTime><Date>Mon Jan 01 2001</Date><Date>")),
        ("two TIMEBLOCKs", real.replace("<TIMEBLOCK>", "<TIMEBLOCK><Date frame=\"0\">Mon Jan 01 2001</Date><Time frame=\"0\">00:00:00.000 000.00</Time></TIMEBLOCK><TIMEBLOCK>")),
        // PCC's order changed: the times' origin is known only at the end.
        ("the header last", move_to_end(real, "CineFileHeader")),
        ("the blocks first", move_to_end(&move_to_end(real, "CameraSetup"), "CineFileHeader")),
        ("no trigger", real.replace(&between(real, "TriggerTime"), "")),
        ("no trigger, header last", move_to_end(&real.replace(&between(real, "TriggerTime"), ""), "CineFileHeader")),
        ("no header", real.replace(&between(real, "CineFileHeader"), "")),
        // Dates: all first, repeated, changed.
        ("dates first", dates_first(real)),
        ("a date repeated", real.replace("<Time frame=\"1\">", "<Date frame=\"1\">Mon Jan 01 2001</Date><Time frame=\"1\">")),
        ("an unused bad date", real.replace("<TIMEBLOCK>", "<TIMEBLOCK><Date frame=\"9\">never</Date>")),
        ("another element in the TIMEBLOCK", real.replace("<TIMEBLOCK>", "<TIMEBLOCK><Note frame=\"3\">x</Note>")),
        ("an element in a Time", real.replace("</Time></TIMEBLOCK>", "<b/></Time></TIMEBLOCK>")),
        ("whitespace after the root", format!("{real}\r\n \t")),
        ("whitespace before the root", real.replacen("<!--", "\n \t<!--", 1)),
        ("a comment after the root", format!("{real}<!-- end -->")),
    ]
}

/// Edits of the real side file `real` that the tree refuses.
fn refused_edits(real: &str) -> Vec<(&'static str, String)> {
    vec![
        // A value given twice, differently: which holds is unknown.
        (
            "two frame rates",
            real.replace(
                "<FrameRateDouble>",
                "<FrameRateDouble>1234</FrameRateDouble><FrameRateDouble>",
            ),
        ),
        (
            "two headers that disagree",
            real.replace(
                "<CineFileHeader>",
                "<CineFileHeader><FirstImageNo>77</FirstImageNo></CineFileHeader><CineFileHeader>",
            ),
        ),
        (
            "a time before its date",
            real.replacen("<Date frame=\"0\">", "<Date frame=\"5\">", 1),
        ),
        (
            "a Date without frame",
            real.replacen("<Date frame=\"0\">", "<Date>", 1),
        ),
        (
            "a frame not a number",
            real.replacen("<Exp frame=\"1\">", "<Exp frame=\"one\">", 1),
        ),
        (
            "an Exp not a number",
            real.replace(">63.853</Exp>", ">fast</Exp>"),
        ),
        (
            "a bad time",
            real.replacen("<Time frame=\"1\">", "<Time frame=\"1\">25:", 1),
        ),
        (
            "a bad trigger",
            real.replace("<TriggerTime><Date>Thu Jul", "<TriggerTime><Date>Thu Jux"),
        ),
        ("a rate not a number", real.replace(">7500<", ">fast<")),
        ("an unknown entity", real.replace(">4064<", ">&nbsp;<")),
        ("a bare ampersand", real.replace(">4064<", ">&<")),
        ("whitespace before the declaration", format!(" {real}")),
        ("a DTD", real.replace("<chd>", "<!DOCTYPE chd><chd>")),
        ("a second root", format!("{real}<chd/>")),
        ("text after the root", format!("{real}x")),
        ("a wrong end tag", real.replace("</RealBPP>", "</realbpp>")),
        (
            "an end tag too many",
            real.replace("</RealBPP>", "</RealBPP></RealBPP>"),
        ),
        (
            "an attribute twice",
            real.replacen("<Exp frame=\"1\">", "<Exp frame=\"1\" frame=\"1\">", 1),
        ),
        (
            "an attribute not quoted",
            real.replacen("<Exp frame=\"1\">", "<Exp frame=1>", 1),
        ),
        ("-- in a comment", real.replace("<!-- xml", "<!-- x -- ml")),
        (
            "a wrong root",
            real.replace("<chd>", "<cine>").replace("</chd>", "</cine>"),
        ),
    ]
}

/// `text` with the first `<name>…</name>` moved to the root's end.
fn move_to_end(text: &str, name: &str) -> String {
    let element = between(text, name);
    text.replacen(&element, "", 1)
        .replace("</chd>", &format!("{element}</chd>"))
}

/// The first `<name>…</name>` of `text`.
fn between(text: &str, name: &str) -> String {
    let a = text.find(&format!("<{name}>")).unwrap();
    let close = format!("</{name}>");
    let b = text[a..].find(&close).unwrap() + a + close.len();
    text[a..b].to_string()
}

/// The TIMEBLOCK with every Date before every Time.
fn dates_first(text: &str) -> String {
    let block = between(text, "TIMEBLOCK");
    let pieces: Vec<&str> = block
        .trim_start_matches("<TIMEBLOCK>")
        .trim_end_matches("</TIMEBLOCK>")
        .split_inclusive("</Date>")
        .flat_map(|s| s.split_inclusive("</Time>"))
        .collect();
    let (dates, times): (Vec<&str>, Vec<&str>) =
        pieces.iter().partition(|p| p.starts_with("<Date"));
    let sorted = format!(
        "<TIMEBLOCK>{}{}</TIMEBLOCK>",
        dates.concat(),
        times.concat()
    );
    assert_ne!(sorted, block);
    text.replace(&block, &sorted)
}

/// A PCC-like side file of `frames` frames, made as it is read.
struct Generated {
    frames: i64,
    next: i64,
    piece: Vec<u8>,
    at: usize,
}

impl Generated {
    const HEAD: &str = "<?xml version=\"1.0\"?>\n<chd><CineFileHeader><FirstImageNo>0</FirstImageNo>\
        <TriggerTime><Date>Tue Nov 24 2026</Date><Time>23:00:00.000 000.00</Time></TriggerTime>\
        </CineFileHeader><CameraSetup><FrameRateDouble>100000</FrameRateDouble></CameraSetup><TIMEBLOCK>";

    fn new(frames: i64) -> Self {
        Generated {
            frames,
            next: 0,
            piece: Self::HEAD.as_bytes().to_vec(),
            at: 0,
        }
    }

    /// The time of frame `n`: `n × 10 µs` after the trigger.
    fn time(n: i64) -> String {
        let us_total = n * 10;
        let (s, us) = (us_total / 1_000_000, us_total % 1_000_000);
        format!(
            "23:{:02}:{:02}.{:03} {:03}.00",
            s / 60,
            s % 60,
            us / 1000,
            us % 1000
        )
    }
}

impl Read for Generated {
    fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
        if self.at == self.piece.len() {
            let (f, n) = (self.frames, self.next);
            self.piece = if n < f {
                format!(
                    "<Date frame=\"{n}\">Tue Nov 24 2026</Date><Time frame=\"{n}\">{}</Time>",
                    Self::time(n)
                )
            } else if n == f {
                "</TIMEBLOCK><EXPOSUREBLOCK>".into()
            } else if n <= 2 * f {
                format!("<Exp frame=\"{}\">9.500</Exp>", n - f - 1)
            } else if n == 2 * f + 1 {
                "</EXPOSUREBLOCK></chd>".into()
            } else {
                String::new()
            }
            .into_bytes();
            self.next += 1;
            self.at = 0;
        }
        let k = (self.piece.len() - self.at).min(out.len());
        out[..k].copy_from_slice(&self.piece[self.at..self.at + k]);
        self.at += k;
        Ok(k)
    }
}

/// A 1 000 000-frame export (~120 MB of XML, past the 64 MiB the tree
/// reader was limited to) reads, made as it is read: only its values are
/// held.
#[test]
fn a_million_frame_side_file_reads_as_a_stream() {
    let frames = 1_000_000;
    let x = pcc_xml::read(BufReader::new(Generated::new(frames))).unwrap();
    assert_eq!((x.times.len(), x.exposures.len()), (1_000_000, 1_000_000));
    let trigger = local_seconds("Tue Nov 24 2026", "23:00:00.000 000.00").unwrap();
    for n in [0, 1, 4_999, 123_457, 999_999] {
        let t = local_seconds("Tue Nov 24 2026", &Generated::time(n)).unwrap();
        assert_eq!(x.times[n as usize], (n, t.since(trigger)));
        assert_eq!(x.exposures[n as usize], (n, 9.5 * 1e-6));
    }
    // The same file, small enough for the tree reader: the same values.
    let mut small = String::new();
    Generated::new(3000).read_to_string(&mut small).unwrap();
    as_the_tree(&small, "3 000 generated frames").unwrap();
}

/// A tree reader over roxmltree, the reference the stream is held to: it
/// checks size and depth before parsing, reads an element's value across
/// comments and processing instructions ([`reference::value`]) and refuses
/// a value given twice differently.
mod reference {
    use dropscope::source::pcc_xml::{local_seconds, LocalInstant, PccXml};

    pub fn parse(text: &str) -> Result<PccXml, String> {
        let doc = roxmltree::Document::parse(text).map_err(|e| format!("not valid XML: {e}"))?;
        let root = doc.root_element();
        if root.tag_name().name() != "chd" {
            return Err(format!(
                "root element is <{}>, not PCC's <chd>",
                root.tag_name().name()
            ));
        }
        one_value_a_field(root)?;
        // A field's first element in any block of its name.
        let text_of = |block: &str, name: &str| -> Option<String> {
            root.children()
                .filter(|b| b.is_element() && b.tag_name().name() == block)
                .find_map(|b| child(b, name))
                .map(|n| value(n).trim().to_string())
        };
        let (bitmap, setup) = ("BitmapInfoHeader", "CameraSetup");
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
        let trigger = root
            .children()
            .filter(|b| b.is_element() && b.tag_name().name() == "CineFileHeader")
            .find_map(|h| child(h, "TriggerTime"))
            .map(|t| {
                let d = child(t, "Date").map(value).unwrap_or_default();
                let tm = child(t, "Time").map(value).unwrap_or_default();
                let (d, tm) = (d.as_str(), tm.as_str());
                local_seconds(d, tm)
                    .ok_or_else(|| format!("TriggerTime {d:?} {tm:?} is not a PCC date/time"))
            });
        let trigger = trigger.transpose()?;
        let instants = timeblock(root)?;
        // Relative to the trigger; without one, to the first listed frame.
        let times = match trigger.or(instants.first().map(|t| t.1)) {
            Some(origin) => instants
                .iter()
                .map(|(f, t)| (*f, t.since(origin)))
                .collect(),
            None => Vec::new(),
        };
        let exposures = exposureblock(root)?;
        Ok(PccXml {
            first_image_no: num(text_of("CineFileHeader", "FirstImageNo"), "FirstImageNo")?,
            image_count: num(text_of("CineFileHeader", "ImageCount"), "ImageCount")?,
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

    /// Every value of a field, in every block of its name: all alike, or
    /// the error a contradicting side file gets.
    fn one_value_a_field(root: roxmltree::Node<'_, '_>) -> Result<(), String> {
        for (block, name) in FIELDS {
            let values: Vec<String> = root
                .children()
                .filter(|b| b.is_element() && b.tag_name().name() == block)
                .flat_map(|b| {
                    b.children()
                        .filter(|n| n.is_element() && n.tag_name().name() == name)
                })
                .map(|n| value(n).trim().to_string())
                .collect();
            if let Some(other) = values.iter().find(|v| **v != values[0]) {
                return Err(format!(
                    "<{name}> is given twice, as {:?} and {other:?}: the side file contradicts \
                 itself (which value holds is unknown); correct it",
                    values[0]
                ));
            }
        }
        Ok(())
    }

    /// The TIMEBLOCK's instants, a frame each.
    fn timeblock(root: roxmltree::Node<'_, '_>) -> Result<Vec<(i64, LocalInstant)>, String> {
        let mut instants = Vec::new();
        if let Some(block) = child(root, "TIMEBLOCK") {
            // Date and Time elements come in pairs sharing a frame attribute.
            let mut date_of_frame: Vec<(i64, String)> = Vec::new();
            for n in block.children().filter(|n| n.is_element()) {
                let frame = frame_attr(n)?;
                let text = value(n);
                let value = text.as_str();
                match n.tag_name().name() {
                    "Date" => date_of_frame.push((frame, text.clone())),
                    "Time" => {
                        let date = date_of_frame
                            .iter()
                            .rev()
                            .find(|(f, _)| *f == frame)
                            .map(|(_, d)| d.as_str())
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
        Ok(instants)
    }

    /// The EXPOSUREBLOCK's exposures (s), a frame each.
    fn exposureblock(root: roxmltree::Node<'_, '_>) -> Result<Vec<(i64, f64)>, String> {
        let mut exposures = Vec::new();
        if let Some(block) = child(root, "EXPOSUREBLOCK") {
            for n in block
                .children()
                .filter(|n| n.is_element() && n.tag_name().name() == "Exp")
            {
                let frame = frame_attr(n)?;
                let us: f64 = value(n)
                    .trim()
                    .parse()
                    .map_err(|_| format!("EXPOSUREBLOCK frame={frame} is not a number"))?;
                exposures.push((frame, us * 1e-6));
            }
        }
        Ok(exposures)
    }

    /// The fields read from the header, bitmap and set-up blocks.
    const FIELDS: [(&str, &str); 14] = [
        ("CineFileHeader", "FirstImageNo"),
        ("CineFileHeader", "ImageCount"),
        ("BitmapInfoHeader", "biWidth"),
        ("BitmapInfoHeader", "biHeight"),
        ("BitmapInfoHeader", "biBitCount"),
        ("CameraSetup", "FrameRateDouble"),
        ("CameraSetup", "FrameRate"),
        ("CameraSetup", "ShutterNs"),
        ("CameraSetup", "Shutter"),
        ("CameraSetup", "RealBPP"),
        ("CameraSetup", "BlackLevel"),
        ("CameraSetup", "WhiteLevel"),
        ("CameraSetup", "bFlipH"),
        ("CameraSetup", "bFlipV"),
    ];

    /// An element's value: its text before its first child element,
    /// comments and processing instructions skipped.
    pub fn value(n: roxmltree::Node<'_, '_>) -> String {
        n.children()
            .take_while(|c| !c.is_element())
            .filter(|c| c.is_text())
            .filter_map(|c| c.text())
            .collect()
    }

    fn child<'a, 'i>(
        parent: roxmltree::Node<'a, 'i>,
        name: &str,
    ) -> Option<roxmltree::Node<'a, 'i>> {
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
}
