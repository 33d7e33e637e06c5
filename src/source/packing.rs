//! Sample (un)packing shared by the cine reader and writer: 8-bit, 16-bit
//! little-endian, and the MSB-first bit-packed P10 / P12L layouts
//! (formats/phantom.md §8.1, §8.4, §8.5).

/// Widen 8-bit samples to `u16` (values unchanged).
pub(crate) fn unpack_u8(src: &[u8], out: &mut [u16]) {
    super::widen::widen_u8(src, out);
}

/// Little-endian 16-bit samples to `u16` (values unchanged).
pub(crate) fn unpack_u16le(src: &[u8], out: &mut [u16]) {
    for (d, s) in out.iter_mut().zip(src.chunks_exact(2)) {
        *d = u16::from_le_bytes([s[0], s[1]]);
    }
}

/// Bytes needed to hold `count` samples of `bits` bits starting `bit_offset`
/// bits into the first byte.
pub(crate) fn packed_span(bit_offset: u64, count: u64, bits: u32) -> u64 {
    (bit_offset + count * u64::from(bits)).div_ceil(8)
}

/// Unpack `out.len()` MSB-first samples of `bits` (10 or 12) bits from `src`,
/// starting `bit_offset` (0‥7) bits into `src[0]`. `src` must hold
/// [`packed_span`] bytes (shorter input leaves the rest of `out` untouched).
///
/// P10: 4 samples in 5 bytes, `p0 = b0<<2 | b1>>6`, … ; P12L: 2 samples in
/// 3 bytes, `p0 = b0<<4 | b1>>4`, `p1 = (b1&0xF)<<8 | b2`.
pub(crate) fn unpack_msb(src: &[u8], bit_offset: u32, bits: u32, out: &mut [u16]) {
    debug_assert!(bit_offset < 8 && (bits == 10 || bits == 12));
    if bit_offset == 0 && bits == 10 {
        let groups = out.len() / 4;
        let whole = groups.min(src.len() / 5);
        for (o, s) in out.chunks_exact_mut(4).zip(src.chunks_exact(5)).take(whole) {
            let (b0, b1, b2, b3, b4) = (
                u16::from(s[0]),
                u16::from(s[1]),
                u16::from(s[2]),
                u16::from(s[3]),
                u16::from(s[4]),
            );
            o[0] = (b0 << 2) | (b1 >> 6);
            o[1] = ((b1 & 0x3F) << 4) | (b2 >> 4);
            o[2] = ((b2 & 0x0F) << 6) | (b3 >> 2);
            o[3] = ((b3 & 0x03) << 8) | b4;
        }
        unpack_generic(src, 40 * whole as u64, bits, &mut out[4 * whole..]);
    } else if bit_offset == 0 && bits == 12 {
        let pairs = out.len() / 2;
        let whole = pairs.min(src.len() / 3);
        for (o, s) in out.chunks_exact_mut(2).zip(src.chunks_exact(3)).take(whole) {
            let (b0, b1, b2) = (u16::from(s[0]), u16::from(s[1]), u16::from(s[2]));
            o[0] = (b0 << 4) | (b1 >> 4);
            o[1] = ((b1 & 0x0F) << 8) | b2;
        }
        unpack_generic(src, 24 * whole as u64, bits, &mut out[2 * whole..]);
    } else {
        unpack_generic(src, u64::from(bit_offset), bits, out);
    }
}

/// Bit-by-bit reference path: any start bit, any sample width ≤ 16.
fn unpack_generic(src: &[u8], start_bit: u64, bits: u32, out: &mut [u16]) {
    let mut bit = start_bit;
    for o in out.iter_mut() {
        let end = bit + u64::from(bits);
        if end.div_ceil(8) > src.len() as u64 {
            return;
        }
        let mut v: u32 = 0;
        // At most 3 bytes cover a ≤16-bit sample at any offset.
        let first = (bit / 8) as usize;
        let last = ((end - 1) / 8) as usize;
        for b in &src[first..=last] {
            v = (v << 8) | u32::from(*b);
        }
        let total_bits = (last - first + 1) as u64 * 8;
        let shift = total_bits - (end - first as u64 * 8);
        *o = ((v >> shift) & ((1u32 << bits) - 1)) as u16;
        bit = end;
    }
}

/// Pack samples MSB-first with `bits` bits each (values must fit; higher bits
/// are masked off). The inverse of [`unpack_msb`] at bit offset 0.
pub(crate) fn pack_msb(samples: &[u16], bits: u32, out: &mut Vec<u8>) {
    let mut acc: u64 = 0;
    let mut n: u32 = 0;
    let mask = (1u64 << bits) - 1;
    for s in samples {
        acc = (acc << bits) | (u64::from(*s) & mask);
        n += bits;
        while n >= 8 {
            n -= 8;
            out.push((acc >> n) as u8);
        }
        acc &= (1u64 << n) - 1;
    }
    if n > 0 {
        out.push((acc << (8 - n)) as u8);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn p10_matches_the_documented_formula() {
        // p0 = b0<<2 | b1>>6 etc. (phantom.md §8.4) on a hand-made group.
        let src = [
            0b1010_1010u8,
            0b1100_1100,
            0b1111_0101,
            0b0110_1111,
            0b0101_0101,
        ];
        let b: Vec<u16> = src.iter().map(|&v| u16::from(v)).collect();
        let mut out = [0u16; 4];
        unpack_msb(&src, 0, 10, &mut out);
        assert_eq!(out[0], (b[0] << 2) | (b[1] >> 6));
        assert_eq!(out[1], ((b[1] & 0x3F) << 4) | (b[2] >> 4));
        assert_eq!(out[2], ((b[2] & 0x0F) << 6) | (b[3] >> 2));
        assert_eq!(out[3], ((b[3] & 0x03) << 8) | b[4]);
        assert_eq!(out, [683, 207, 347, 853]);
    }

    #[test]
    fn pack_then_unpack_is_identity_at_every_offset() {
        for bits in [10u32, 12] {
            let samples: Vec<u16> = (0..37u32)
                .map(|i| ((i * 2654435761) >> 7) as u16 & ((1 << bits) - 1) as u16)
                .collect();
            let mut packed = Vec::new();
            pack_msb(&samples, bits, &mut packed);
            assert_eq!(packed.len() as u64, packed_span(0, 37, bits));
            let mut out = vec![0u16; 37];
            unpack_msb(&packed, 0, bits, &mut out);
            assert_eq!(out, samples);
            // Start at sample k: the fast and the generic paths must agree.
            for k in 0..8usize {
                let start_bit = k as u64 * u64::from(bits);
                let byte = (start_bit / 8) as usize;
                let mut part = vec![0u16; 37 - k];
                unpack_msb(&packed[byte..], (start_bit % 8) as u32, bits, &mut part);
                assert_eq!(part, samples[k..], "bits {bits} start {k}");
            }
        }
    }
}
