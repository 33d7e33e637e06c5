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
fn deep_nesting_is_refused_as_it_is_read() {
    // 100 000 levels would overflow the stack of a tree parser.
    let deep = format!(
        "<chd>{}{}</chd>",
        "<a>".repeat(100_000),
        "</a>".repeat(100_000)
    );
    let e = parse(&deep).unwrap_err();
    // The 65th element starts after `<chd>` and 63 `<a>`.
    assert!(e.contains("nested more than 64 deep (at byte 194)"), "{e}");
    // 64 levels are read; comments, CDATA, quoted `>` and empty
    // elements do not nest.
    let nested = |levels: usize| {
        format!(
            "<?xml version=\"1.0\"?><chd><!-- <a><a> -->{}<x a=\"b>\" b='>'/><![CDATA[<c><c>]]>\
                 <CameraSetup><FrameRate>10</FrameRate>{}<e/>{}</CameraSetup></chd>",
            "<e/>".repeat(100),
            "<a>".repeat(levels - 2),
            "</a>".repeat(levels - 2)
        )
    };
    assert_eq!(parse(&nested(64)).unwrap().fps, Some(10.0));
    let e = parse(&nested(65)).unwrap_err();
    assert!(e.contains("nested more than 64 deep"), "{e}");
}

#[test]
fn frames_past_the_limit_and_long_pieces_are_refused() {
    let exps = |n: usize| {
        let e: String = (0..n)
            .map(|k| format!("<Exp frame=\"{k}\">9.5</Exp>"))
            .collect();
        format!("<chd><EXPOSUREBLOCK>{e}</EXPOSUREBLOCK></chd>")
    };
    assert_eq!(
        read_limited(exps(10).as_bytes(), 10)
            .unwrap()
            .exposures
            .len(),
        10
    );
    let e = read_limited(exps(11).as_bytes(), 10).unwrap_err();
    assert!(e.contains("EXPOSUREBLOCK lists more than 10 frames"), "{e}");
    let times = |n: usize| {
        let t: String = (0..n)
            .map(|k| {
                format!(
                    "<Date frame=\"{k}\">Thu Jan 01 1970</Date>\
                         <Time frame=\"{k}\">00:00:00.{k:03} 000.00</Time>"
                )
            })
            .collect();
        format!("<chd><TIMEBLOCK>{t}</TIMEBLOCK></chd>")
    };
    assert_eq!(
        read_limited(times(10).as_bytes(), 10).unwrap().times.len(),
        10
    );
    let e = read_limited(times(11).as_bytes(), 10).unwrap_err();
    assert!(e.contains("TIMEBLOCK lists more than 10 frames"), "{e}");
    // Consecutive frames with one date are one run of dates, whatever
    // their count; a frame listed again or another date starts one.
    let mut dates = Dates::default();
    for k in 0..1000 {
        dates.push(k, "Thu Jan 01 1970".into(), 2).unwrap();
    }
    dates.push(5, "Fri Jan 02 1970".into(), 2).unwrap();
    assert_eq!(
        (dates.of(5), dates.of(6)),
        (Some("Fri Jan 02 1970"), Some("Thu Jan 01 1970"))
    );
    assert_eq!(dates.of(1000), None);
    assert!(dates.push(7, "Thu Jan 01 1970".into(), 2).is_err());
    // One text of 2 MiB: refused before it is read whole.
    let long = format!(
        "<chd><Description>{}</Description></chd>",
        "x".repeat(2 << 20)
    );
    let e = parse(&long).unwrap_err();
    assert!(e.contains("longer than 1 MiB at byte 18"), "{e}");
    // A value made of many short pieces: refused past 1 MiB too.
    let pieces = format!(
        "<chd><CameraSetup><RealBPP>{}</RealBPP></CameraSetup></chd>",
        "&#49;".repeat((1 << 20) + 1)
    );
    let e = parse(&pieces).unwrap_err();
    assert!(
        e.contains("<RealBPP> holds more than 1 MiB of text"),
        "{}",
        &e[..e.len().min(200)]
    );
    // A file that cannot be read names the failure.
    struct Failing;
    impl Read for Failing {
        fn read(&mut self, _: &mut [u8]) -> io::Result<usize> {
            Err(io::Error::other("disk gone"))
        }
    }
    let e = read(io::BufReader::new(Failing)).unwrap_err();
    assert_eq!(e, "reading it: disk gone");
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
fn wrong_root_bad_numbers_and_bad_xml_are_errors() {
    assert!(parse("<cine/>").unwrap_err().contains("<chd>"));
    for (xml, says) in [
        ("", "not valid XML: no root element"),
        ("<chd><a></chd>", "not valid XML at byte 8"),
        (
            "<chd><a>",
            "not valid XML: the file ends inside <a> (cut short?)",
        ),
        (
            "<chd/><chd/>",
            "not valid XML at byte 6: a second root element <chd>",
        ),
        (
            "<chd>&nbsp;</chd>",
            "not valid XML at byte 5: unknown entity &nbsp;",
        ),
        ("<!DOCTYPE chd><chd/>", "not valid XML at byte 0: a DTD"),
    ] {
        let e = parse(xml).unwrap_err();
        assert!(e.contains(says), "{xml:?}: {e}");
    }
    let e = parse("<chd><CameraSetup><RealBPP>twelve</RealBPP></CameraSetup></chd>").unwrap_err();
    assert!(e.contains("RealBPP"), "{e}");
}
