use super::side_file::{gaps_of, look_through};
use super::*;
use crate::source::FrameNumbers;

#[test]
fn names_split_into_prefix_number_and_kind() {
    let p = |n: &str| parse_frame_name(n).map(|(a, b, _)| (a, b));
    assert_eq!(p("run_000012.tif"), Some(("run_".into(), 12)));
    assert_eq!(p("run_-00005.tif"), Some(("run_".into(), -5)));
    assert_eq!(p("-3.png"), Some(("".into(), -3)));
    assert_eq!(p("img-0004.png"), Some(("img-".into(), 4)));
    assert_eq!(p("img--4.png"), Some(("img-".into(), -4)));
    assert_eq!(p("Img7.BMP"), Some(("Img".into(), 7)));
    assert_eq!(p("notes.txt"), None);
    assert_eq!(p("background.tif"), None);
    assert_eq!(p("run.xml"), None);
}

#[test]
fn gaps_are_inclusive_ranges_of_missing_numbers() {
    let numbers = |v: &[i64]| v.iter().copied().collect::<FrameNumbers>();
    assert_eq!(
        gaps_of(&numbers(&[-2, -1, 0, 3, 4, 6])),
        vec![(1, 2), (5, 5)]
    );
    assert!(gaps_of(&numbers(&[5])).is_empty());
}

/// The look through a side file finds `<chd` and checks UTF-8 across
/// its 64 kB blocks: a character or the tag cut by a block's end.
#[test]
fn a_look_through_sees_across_its_blocks() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("x.xml");
    let look = |bytes: &[u8]| {
        std::fs::write(&path, bytes).unwrap();
        let l = look_through(&path).unwrap();
        (l.utf8, l.chd)
    };
    let block = 1 << 16;
    for cut in 1..4 {
        // "<chd" and a 3-byte character ending `cut` bytes into the next block.
        let mut chd = vec![b' '; block - 4 + cut];
        chd.extend_from_slice(b"<chd");
        assert_eq!(look(&chd), (true, true), "<chd cut at {cut}");
        let mut euro = vec![b' '; block - 3 + cut];
        euro.extend_from_slice("\u{20ac}<ch".as_bytes());
        assert_eq!(look(&euro), (true, false), "a character cut at {cut}");
        let mut broken = euro.clone();
        broken[block - 3 + cut + 1] = b'x';
        assert_eq!(look(&broken), (false, false));
        // A character the file ends inside.
        assert_eq!(look(&euro[..block - 3 + cut + 2]), (false, false));
    }
    assert_eq!(look(b""), (true, false));
    assert_eq!(look(b"\xff<chd>"), (false, true));
}
