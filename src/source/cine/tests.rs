use super::read::reverse_rows;

#[test]
fn rows_are_reversed_in_place_for_odd_and_even_counts() {
    for n in [0usize, 1, 2, 3, 6, 7] {
        let row = 5;
        let mut buf: Vec<u8> = (0..n * row).map(|i| i as u8).collect();
        reverse_rows(&mut buf, row);
        for (j, chunk) in buf.chunks_exact(row).enumerate() {
            let k = n - 1 - j;
            let want: Vec<u8> = (k * row..(k + 1) * row).map(|i| i as u8).collect();
            assert_eq!(chunk, &want[..], "n = {n}, row {j}");
        }
    }
}
