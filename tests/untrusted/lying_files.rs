//! Files that lie: a cache entry edited by hand, a PCC side file, numbers
//! out of physical range, a frame too large to decode, a turned TIFF.

use super::*;
use dropscope::dataset::DropStatus;

/// Class: a cache entry changed by hand (`v_impact_m_s` → 9.99 in
/// runs/<run>.json) is not reused: the run is measured again, with a note.
#[test]
fn a_cache_entry_edited_by_hand_is_not_believed() {
    let dir = tempfile::tempdir().unwrap();
    let run = copy_drop(dir.path(), DROP, |x| x);
    let out = dir.path().join("out");
    let o = process(&[&run], &out, &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let measured = read_csv(&out.join("drops.csv")).unwrap()[0]
        .v_impact_m_s
        .unwrap();
    let entry = out.join("runs").join(format!("{DROP}.json"));
    let text = std::fs::read_to_string(&entry).unwrap();
    let field = format!("\"v_impact_m_s\": {measured}");
    assert!(text.contains(&field), "{text}");
    std::fs::write(&entry, text.replace(&field, "\"v_impact_m_s\": 9.99")).unwrap();
    let o = process(&[&run], &out, &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let row = &read_csv(&out.join("drops.csv")).unwrap()[0];
    assert_eq!(row.v_impact_m_s, Some(measured));
    assert!(
        stderr(&o).contains("changed since dropscope wrote it"),
        "{}",
        stderr(&o)
    );
}

/// `dropscope inspect DIR --json` as JSON.
fn inspect(dir: &Path) -> Result<serde_json::Value, String> {
    let o = dropscope()
        .arg("inspect")
        .arg(dir)
        .arg("--json")
        .output()
        .unwrap();
    if o.status.success() {
        Ok(serde_json::from_slice(&o.stdout).unwrap())
    } else {
        Err(stderr(&o))
    }
}

/// `xml` with `from` replaced by `to`, which must be there.
fn edit(xml: &str, from: &str, to: &str) -> String {
    assert!(xml.contains(from), "{from} not in the side file");
    xml.replacen(from, to, 1)
}

/// Class: the PCC side file says what it says, or is refused. A comment
/// inside a value does not cut it; a value given twice differently is
/// refused; a TIMEBLOCK missing a frame, or listing one under a stray
/// number, is kept (the irregular time beside it still flagged) and said; files renumbered from 0 get the side
/// file's numbers and times; a side file of other frames is refused.
#[test]
fn a_side_file_is_read_whole_and_applied_only_to_its_frames() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let shutter = "<ShutterNs>50000</ShutterNs>";
    let split = copy_drop(d, "split", |x| {
        edit(&x, shutter, "<ShutterNs>50<!---->000</ShutterNs>")
    });
    let v = inspect(&split).unwrap();
    assert_eq!(v["exposure_s"].as_f64(), Some(50e-6), "{v}");
    let twice = copy_drop(d, "twice", |x| {
        edit(
            &x,
            shutter,
            "<ShutterNs>50000</ShutterNs><ShutterNs>50</ShutterNs>",
        )
    });
    let e = inspect(&twice).unwrap_err();
    assert!(e.contains("<ShutterNs> is given twice"), "{e}");

    // An irregular time (3 µs off, 3 % of an interval) beside a missing one.
    let out = d.join("out");
    let irregular = copy_drop(d, "irregular", |x| {
        let x = edit(
            &x,
            "<Time frame=\"-25\">10:00:59.997 500.00</Time>",
            "<Time frame=\"-25\">10:00:59.997 503.00</Time>",
        );
        let x = edit(
            &x,
            "<Date frame=\"-20\">Thu Jun 13 2019</Date><Time frame=\"-20\">10:00:59.998 000.00</Time>",
            "",
        );
        // A stray frame number: frame -15's time listed under 9999.
        edit(
            &x,
            "<Date frame=\"-15\">Thu Jun 13 2019</Date><Time frame=\"-15\">",
            "<Date frame=\"9999\">Thu Jun 13 2019</Date><Time frame=\"9999\">",
        )
    });
    let o = process(&[&irregular], &out, &[]);
    assert!(o.status.code().is_some_and(|c| c < 2), "{}", stderr(&o));
    let row = &read_csv(&out.join("drops.csv")).unwrap()[0];
    assert_eq!(row.status, DropStatus::Warning, "{}", row.reason);
    assert!(row.flags.contains("time_irregular"), "{}", row.flags);
    assert!(
        row.reason.contains("no time for 2 of the 87 frames"),
        "{}",
        row.reason
    );

    // The frames renumbered from 0, as `dropscope export` names them.
    let plain = copy_drop(d, "plain", |x| x);
    let renumbered = d.join("renumbered");
    std::fs::create_dir(&renumbered).unwrap();
    let mut pngs: Vec<(i64, PathBuf)> = std::fs::read_dir(&plain)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "png"))
        .map(|p| {
            let stem = p.file_stem().unwrap().to_str().unwrap().to_string();
            let n: i64 = stem.rsplit_once('_').unwrap().1.parse().unwrap();
            (n, p)
        })
        .collect();
    pngs.sort();
    for (i, (_, p)) in pngs.iter().enumerate() {
        std::fs::copy(p, renumbered.join(format!("renumbered_{i:03}.png"))).unwrap();
    }
    std::fs::copy(
        plain.join(format!("{DROP}.xml")),
        renumbered.join("renumbered.xml"),
    )
    .unwrap();
    let out2 = d.join("out2");
    let o = process(&[&plain, &renumbered], &out2, &[]);
    assert!(o.status.code().is_some_and(|c| c < 2), "{}", stderr(&o));
    let rows = read_csv(&out2.join("drops.csv")).unwrap();
    let (a, b) = (rows[0].t_contact_s.unwrap(), rows[1].t_contact_s.unwrap());
    assert!((a - b).abs() < 1e-9, "t_contact {a} s, renumbered {b} s");

    // A side file of other frames (another export's count) is not applied.
    let other = copy_drop(d, "other", |x| {
        edit(&x, "<ImageCount>87<", "<ImageCount>40<")
    });
    std::fs::remove_file(other.join(format!("{DROP}_-000030.png"))).unwrap();
    let e = inspect(&other).unwrap_err();
    assert!(
        e.contains("not their side file") && e.contains(".xml"),
        "{e}"
    );
}

/// Class: numbers out of any physical range. A frame rate of 1e300 in
/// pipeline.toml is refused by check-config naming the key; a density of
/// 1e308 or 1e-308 in a manifest naming the column; in a hand-made drops.csv given
/// to `collapse`, the row is skipped saying why, never used as Ψ = Ξ = 0.
#[test]
fn numbers_out_of_physical_range_are_refused_where_they_enter() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cfg = d.join("p.toml");
    std::fs::write(&cfg, "[camera]\nfps = 1e300\n").unwrap();
    let o = dropscope()
        .args(["check-config", "--config"])
        .arg(&cfg)
        .output()
        .unwrap();
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("camera.fps") && e.contains("1e7"), "{e}");
    copy_drop(d, DROP, |x| x);
    // 1e308 overflows the force constants; 1e-308 sent the log axes' tick
    // code into an unbounded loop.
    for density in ["1e308", "1e-308"] {
        std::fs::write(
            d.join("runs.csv"),
            format!(
                "run,path,sphere_radius_mm,sphere_density_kg_m3\n{DROP},{DROP},4.5,{density}\n"
            ),
        )
        .unwrap();
        let mut c = dropscope();
        c.args(["process", "--no-animation", "--manifest"])
            .arg(d.join("runs.csv"))
            .arg("--out")
            .arg(d.join("out"));
        let o = within(c, Duration::from_secs(120))
            .unwrap_or_else(|| panic!("density {density}: still running after 120 s"));
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{density}: {e}");
        assert!(
            e.contains("sphere_density_kg_m3") && e.contains("row 2") && e.contains("1e5 kg/m³"),
            "{e}"
        );
    }
    // A drops.csv edited by hand.
    let out = d.join("made");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(
        out.join("drops.csv"),
        "run,sphere_radius_mm,sphere_density_kg_m3,v_impact_m_s,v_rebound_m_s,restitution,\
         delta_max_mm,a_max_mm,a_geom_mm,tau_c_ms,t_contact_s,t_rebound_s,mm_per_px,\
         surface_row_px,status\n\
         a,4.5,7800,2.0,,,1.2,2.5,,5.0,,,,,ok\n\
         b,4.5,1e308,2.0,,,1.2,2.5,,5.0,,,,,ok\n\
         c,4.5,7800,1e-160,,,1.2,2.5,,5.0,,,,,ok\n",
    )
    .unwrap();
    let mut c = dropscope();
    c.arg("collapse").arg(out.join("drops.csv"));
    let o = within(c, Duration::from_secs(120)).expect("collapse still running after 120 s");
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let text = std::fs::read_to_string(out.join("collapse.csv")).unwrap();
    let mut r = csv::Reader::from_reader(text.as_bytes());
    let h = r.headers().unwrap().clone();
    let col = |n: &str| h.iter().position(|c| c == n).unwrap();
    let rows: Vec<csv::StringRecord> = r.records().map(|x| x.unwrap()).collect();
    assert_eq!(&rows[0][col("used")], "true");
    for row in &rows[1..] {
        assert_eq!(&row[col("used")], "false", "{row:?}");
        assert_eq!(&row[col("Psi")], "", "{row:?}");
    }
    assert!(
        rows[1][col("note")].contains("sphere_density_kg_m3 = 1e308"),
        "{:?}",
        rows[1]
    );
}

/// A grey PNG of `width` × `height` pixels whose rows are all zero,
/// compressed as far as deflate goes (~1 kB per MB of pixels).
fn flat_png(path: &Path, width: u32, height: u32) {
    let f = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut enc = png::Encoder::new(f, width, height);
    enc.set_color(png::ColorType::Grayscale);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_compression(png::Compression::High);
    let mut w = enc.write_header().unwrap().into_stream_writer().unwrap();
    let row = vec![0u8; width as usize];
    for _ in 0..height {
        std::io::Write::write_all(&mut w, &row).unwrap();
    }
    w.finish().unwrap();
}

/// Class: a frame too large to decode within a worker's memory is
/// refused from its header, in every format (a 30 000² PNG of 0.9 MB took
/// 8.8 GB), naming the file and its size.
#[test]
fn a_frame_too_large_to_decode_is_refused_from_its_header() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("huge");
    std::fs::create_dir(&run).unwrap();
    flat_png(&run.join("huge_000001.png"), 30_000, 30_000);
    let e = inspect(&run).unwrap_err();
    assert!(
        e.contains("huge_000001.png") && e.contains("30000×30000") && e.contains("8192 × 4096"),
        "{e}"
    );
    // A deflate TIFF of 16 000² (3.75 GB a worker to decode) from a
    // 1 kB file: refused from its tags.
    let deflated = dir.path().join("deflated");
    std::fs::create_dir(&deflated).unwrap();
    let strip = fdeflate::compress_to_vec(&vec![0u8; 1 << 20]);
    for i in 0..3 {
        std::fs::write(
            deflated.join(format!("t_{i:03}.tif")),
            tiff(16_000, 16_000, 1, 8, strip.clone()),
        )
        .unwrap();
    }
    let e = inspect(&deflated).unwrap_err();
    assert!(
        e.contains("t_000.tif") && e.contains("16000×16000") && e.contains("8192 × 4096"),
        "{e}"
    );
    // In a job, the run fails and the next one is measured.
    copy_drop(dir.path(), DROP, |x| x);
    let manifest = dir.path().join("runs.csv");
    std::fs::write(
        &manifest,
        format!(
            "run,path,sphere_radius_mm,fps\nhuge,huge,4.5,10000\ndeflated,deflated,4.5,10000\n\
             {DROP},{DROP},4.5,10000\n"
        ),
    )
    .unwrap();
    let out = dir.path().join("out");
    let o = dropscope()
        .args(["process", "--no-animation", "--manifest"])
        .arg(&manifest)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let rows = read_csv(&out.join("drops.csv")).unwrap();
    let status: Vec<(&str, DropStatus)> = rows.iter().map(|r| (r.run.as_str(), r.status)).collect();
    assert_eq!(
        status,
        [
            ("huge", DropStatus::Failed),
            ("deflated", DropStatus::Failed),
            (DROP, DropStatus::Ok)
        ],
        "{}",
        stderr(&o)
    );
    assert!(rows[0].reason.contains("30000×30000"), "{}", rows[0].reason);
}

/// An 8-bit grey little-endian TIFF of `w` × `h` with `orientation`.
fn tiff_with_orientation(w: u16, h: u16, orientation: u16) -> Vec<u8> {
    let pixels = (0..u32::from(w) * u32::from(h)).map(|i| (i % 251) as u8);
    tiff(w, h, orientation, 1, pixels.collect())
}

/// An 8-bit grey little-endian TIFF of `w` × `h` with `orientation` and
/// `compression` (1 none, 8 deflate), one strip holding `data`.
fn tiff(w: u16, h: u16, orientation: u16, compression: u16, data: Vec<u8>) -> Vec<u8> {
    let entries: [(u16, u16, u32, u32); 9] = [
        (256, 3, 1, u32::from(w)),
        (257, 3, 1, u32::from(h)),
        (258, 3, 1, 8),
        (259, 3, 1, u32::from(compression)),
        (262, 3, 1, 1),
        (273, 4, 1, 8 + 2 + 9 * 12 + 4),
        (274, 3, 1, u32::from(orientation)),
        (277, 3, 1, 1),
        (279, 4, 1, data.len() as u32),
    ];
    let mut b = b"II*\0".to_vec();
    b.extend_from_slice(&8u32.to_le_bytes());
    b.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    for (tag, ty, count, value) in entries {
        b.extend_from_slice(&tag.to_le_bytes());
        b.extend_from_slice(&ty.to_le_bytes());
        b.extend_from_slice(&count.to_le_bytes());
        b.extend_from_slice(&value.to_le_bytes());
    }
    b.extend_from_slice(&0u32.to_le_bytes());
    b.extend(data);
    b
}

/// Unclear cases made clear: a TIFF whose Orientation tag says it is shown
/// turned is refused saying so (not measured upside down and blamed on
/// the sphere); a run named with a space and non-ASCII letters has its
/// overlay and figure in the report.
#[test]
fn a_turned_tiff_is_refused_and_any_valid_name_gets_its_overlay() {
    let dir = tempfile::tempdir().unwrap();
    let turned = dir.path().join("turned");
    std::fs::create_dir(&turned).unwrap();
    for i in 0..3 {
        std::fs::write(
            turned.join(format!("t_{i:03}.tif")),
            tiff_with_orientation(16, 12, 3),
        )
        .unwrap();
    }
    let e = inspect(&turned).unwrap_err();
    assert!(
        e.contains("Orientation tag 3") && e.contains("turned 180°"),
        "{e}"
    );
    let upright = dir.path().join("upright");
    std::fs::create_dir(&upright).unwrap();
    for i in 0..3 {
        std::fs::write(
            upright.join(format!("t_{i:03}.tif")),
            tiff_with_orientation(16, 12, 1),
        )
        .unwrap();
    }
    let mut opts = dropscope();
    opts.arg("inspect")
        .arg(&upright)
        .args(["--fps", "1000", "--json"]);
    let o = opts.output().unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));

    let name = "drop 7 Größe";
    let run = copy_drop(dir.path(), name, |x| x);
    let out = dir.path().join("out");
    let o = process(&[&run], &out, &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let o = dropscope()
        .arg("collapse")
        .arg(out.join("drops.csv"))
        .output()
        .unwrap();
    assert!(o.status.code().is_some_and(|c| c < 2), "{}", stderr(&o));
    let o = dropscope().arg("report").arg(&out).output().unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(out
        .join("plots/drops")
        .join(format!("{name}.svg"))
        .is_file());
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    let url = "plots/overlays/drop%207%20Gr%C3%B6%C3%9Fe.png";
    assert!(html.contains(url), "no overlay for {name:?}");
    assert!(html.contains("plots/drops/drop%207%20Gr%C3%B6%C3%9Fe.svg"));
}
