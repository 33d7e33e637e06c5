//! The small pieces of HTML the report is made of: escaping, base64 data
//! URIs and numbers with their uncertainties.

/// Escape text for HTML element content and double- or single-quoted
/// attribute values: `& < > " '` become character references. Every string
/// that comes from input (run names, reasons, paths, JSON text) goes
/// through this before it reaches the page.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            _ => out.push(c),
        }
    }
    out
}

const B64: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

/// Standard base64 (RFC 4648 §4, with `=` padding).
pub fn base64(bytes: &[u8]) -> String {
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for (i, shift) in [18, 12, 6, 0].into_iter().enumerate() {
            if i <= chunk.len() {
                out.push(B64[((n >> shift) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// A `data:` URI holding `bytes` of the given media type.
pub fn data_uri(media_type: &str, bytes: &[u8]) -> String {
    format!("data:{media_type};base64,{}", base64(bytes))
}

/// Decimal exponent of |x| (x finite, non-zero).
fn exponent(x: f64) -> i32 {
    x.abs().log10().floor() as i32
}

/// Values outside [1e-3, 1e5) are written with a power of ten.
fn scientific(e: i32) -> bool {
    !(-3..5).contains(&e)
}

/// `x` rounded to `decimals` places (negative: to tens, hundreds, …).
fn fixed(x: f64, decimals: i32) -> String {
    if decimals >= 0 {
        format!("{x:.*}", decimals as usize)
    } else {
        let p = 10f64.powi(-decimals);
        format!("{:.0}", (x / p).round() * p)
    }
}

/// A value without an uncertainty: 6 significant digits (HTML).
pub fn num(x: f64) -> String {
    sig(x, 6)
}

/// A value to `digits` significant digits (HTML), with a power of ten
/// outside [1e-3, 1e5).
pub fn sig(x: f64, digits: i32) -> String {
    if !x.is_finite() {
        return escape(&x.to_string());
    }
    if x == 0.0 {
        return "0".into();
    }
    let e = exponent(x);
    if scientific(e) {
        let m = x / 10f64.powi(e);
        let m = trim(&format!("{m:.*}", (digits - 1).max(0) as usize));
        format!("{m}×10<sup>{e}</sup>")
    } else {
        trim(&fixed(x, (digits - 1 - e).max(0)))
    }
}

/// `x` written to the decimal place of an error `err` (two significant
/// digits of it), as [`pm`] writes a value; `sig(x, 6)` when that does not
/// apply (no error, or a value needing a power of ten).
pub fn at_precision_of(x: f64, err: Option<f64>) -> String {
    match err.filter(|e| e.is_finite() && *e > 0.0) {
        Some(e) if x.is_finite() && x != 0.0 && !scientific(exponent(x)) => {
            fixed(x, 1 - exponent(e))
        }
        _ => num(x),
    }
}

fn trim(s: &str) -> String {
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s.to_string()
    }
}

/// `value ± err` as HTML, the error to two significant digits and the value
/// to the same decimal place (a no-break space after ±, so a narrow
/// column breaks the line before it); with a common power of ten outside
/// [1e-3, 1e5). Without a usable error: the value alone, marked
/// "error unknown" in its tooltip.
pub fn pm(value: f64, err: Option<f64>) -> String {
    let Some(err) = err.filter(|e| e.is_finite() && *e > 0.0) else {
        return if value.is_finite() {
            format!("<span title=\"error unknown\">{}</span>", num(value))
        } else {
            num(value)
        };
    };
    if !value.is_finite() {
        return num(value);
    }
    // An error below the sixth significant digit (a fit of exact data)
    // would print a screenful of digits: value and error each on their own.
    if value != 0.0 && err < value.abs() * 1e-6 {
        return format!("{} ±\u{a0}{}", num(value), sig(err, 2));
    }
    let e = if value == 0.0 {
        exponent(err)
    } else {
        exponent(value)
    };
    let (scale, suffix) = if scientific(e) {
        (10f64.powi(e), format!("×10<sup>{e}</sup>"))
    } else {
        (1.0, String::new())
    };
    let (v, s) = (value / scale, err / scale);
    let decimals = 1 - exponent(s);
    let body = format!("{} ±\u{a0}{}", fixed(v, decimals), fixed(s, decimals));
    if suffix.is_empty() {
        body
    } else {
        format!("({body}){suffix}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escape_neutralises_every_markup_character() {
        assert_eq!(
            escape(r#"<script>alert("x&y")</script> 'q'"#),
            "&lt;script&gt;alert(&quot;x&amp;y&quot;)&lt;/script&gt; &#39;q&#39;"
        );
        assert_eq!(escape("R4.5mm_H12cm_01 δ"), "R4.5mm_H12cm_01 δ");
    }

    /// The RFC 4648 §10 test vectors.
    #[test]
    fn base64_matches_the_rfc_vectors() {
        let cases = [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ];
        for (plain, coded) in cases {
            assert_eq!(base64(plain.as_bytes()), coded, "{plain:?}");
        }
        assert_eq!(base64(&[0xff, 0xfe, 0x00]), "//4A");
    }

    #[test]
    fn uncertainties_set_the_printed_digits() {
        assert_eq!(
            pm(0.5424205690, Some(0.0000387853)),
            "0.542421 ±\u{a0}0.000039"
        );
        assert_eq!(pm(2.772951951, Some(0.000506)), "2.77295 ±\u{a0}0.00051");
        assert_eq!(pm(1.2224793, Some(0.0030969)), "1.2225 ±\u{a0}0.0031");
        assert_eq!(pm(-0.3333, Some(0.012)), "-0.333 ±\u{a0}0.012");
        assert_eq!(pm(152.4, Some(37.0)), "152 ±\u{a0}37");
        assert_eq!(pm(1234.0, Some(560.0)), "1230 ±\u{a0}560");
        assert_eq!(
            pm(2657038.55, Some(54321.8)),
            "(2.657 ±\u{a0}0.054)×10<sup>6</sup>"
        );
        assert_eq!(
            pm(0.0000567354, Some(2.5477e-7)),
            "(5.674 ±\u{a0}0.025)×10<sup>-5</sup>"
        );
        assert_eq!(pm(1.5, None), "<span title=\"error unknown\">1.5</span>");
        assert_eq!(
            pm(2.0 + 4.4e-16, Some(1.5e-16)),
            "2 ±\u{a0}1.5×10<sup>-16</sup>"
        );
        assert_eq!(num(3.5332775005708976), "3.53328");
        assert_eq!(sig(0.857063, 3), "0.857");
        assert_eq!(at_precision_of(1.23092, Some(0.019)), "1.231");
        assert_eq!(at_precision_of(2.5e-7, Some(1e-8)), "2.5×10<sup>-7</sup>");
        assert_eq!(num(4.2e-6), "4.2×10<sup>-6</sup>");
    }
}
