//! Number syntax of REND3R's assembler (SPEC.md §3.4), reproduced exactly: Python `int()`
//! after removing `_` (with `0x`/`0b` prefixes), and Python `float()` rounded once from
//! f64 to binary16 (round to nearest even), with the integer fallback.

use half::f16;

/// Parses an unsigned integer as REND3R's assembler does; `None` when the text is not one.
#[must_use]
pub fn parse_uint(text: &str) -> Option<u64> {
    let s: String = text.chars().filter(|&c| c != '_').collect();
    let s = s.trim();
    if s.len() > 2 && s.starts_with("0x") {
        return u64::from_str_radix(&s[2..], 16).ok();
    }
    if s.starts_with("0b") {
        return u64::from_str_radix(s.get(2..)?, 2).ok();
    }
    let digits = s.strip_prefix('+').unwrap_or(s);
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse::<u64>().ok()
}

/// Python `float()` on already-lowercased text: decimal with optional exponent, `inf`,
/// `infinity`, `nan`, a sign, and `_` only between digits.
#[must_use]
pub fn parse_python_float(text: &str) -> Option<f64> {
    let s = text.trim();
    let b = s.as_bytes();
    // Underscores must sit between two digits.
    for (i, &c) in b.iter().enumerate() {
        if c == b'_' && !(i > 0 && b[i - 1].is_ascii_digit() && b.get(i + 1).is_some_and(|d| d.is_ascii_digit())) {
            return None;
        }
    }
    let s: String = s.chars().filter(|&c| c != '_').collect();
    let body = s.strip_prefix(['+', '-']).unwrap_or(&s);
    match body {
        "inf" | "infinity" | "nan" => return s.parse::<f64>().ok(),
        _ => {}
    }
    // Only digits, one '.', and an exponent: no hex floats, no other words.
    let mut seen_digit = false;
    let mut chars = body.chars().peekable();
    while let Some(&c) = chars.peek() {
        if c.is_ascii_digit() {
            seen_digit = true;
            chars.next();
        } else if c == '.' {
            chars.next();
        } else {
            break;
        }
    }
    if !seen_digit || body.matches('.').count() > 1 {
        return None;
    }
    if let Some(c) = chars.next() {
        if c != 'e' {
            return None;
        }
        let rest: String = chars.collect();
        let exp = rest.strip_prefix(['+', '-']).unwrap_or(&rest);
        if exp.is_empty() || !exp.bytes().all(|b| b.is_ascii_digit()) {
            return None;
        }
    }
    s.parse::<f64>().ok()
}

/// The binary16 bits of a float-kind operand: `float()` then f64→f16 (RNE); if `float()`
/// rejects the text, a 16-bit unsigned integer read as a *signed* 16-bit value.
#[must_use]
pub fn parse_f16_operand(text: &str) -> Option<u16> {
    if let Some(v) = parse_python_float(text) {
        return Some(f16::from_f64(v).to_bits());
    }
    let u = parse_uint(text)?;
    let u = u16::try_from(u).ok()?;
    Some(f16::from_f64(u as i16 as f64).to_bits())
}

/// The shortest decimal text that `parse_f16_operand` turns back into `bits` (for the
/// disassembler). `None` for NaNs, which have no exact decimal form.
#[must_use]
pub fn f16_to_text(bits: u16) -> Option<String> {
    let v = f16::from_bits(bits);
    if v.is_nan() {
        return None;
    }
    if v.is_infinite() {
        return Some(if v.is_sign_negative() { "-inf".into() } else { "inf".into() });
    }
    let x = v.to_f64();
    for prec in 0..17 {
        let s = format!("{x:.prec$}");
        if parse_f16_operand(&s) == Some(bits) {
            return Some(s);
        }
        let e = format!("{x:.prec$e}");
        if parse_f16_operand(&e) == Some(bits) {
            return Some(e);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integers() {
        assert_eq!(parse_uint("0b00000_000000_11111"), Some(31));
        assert_eq!(parse_uint("0x1F"), Some(31), "Python int(s, 16) takes either case of digit");
        assert_eq!(parse_uint("0x1f"), Some(31));
        assert_eq!(parse_uint("+12"), Some(12));
        assert_eq!(parse_uint("1_000"), Some(1000));
        assert_eq!(parse_uint("-1"), None);
        assert_eq!(parse_uint("1.0"), None);
        assert_eq!(parse_uint("0x"), None);
    }

    #[test]
    fn floats_as_the_spec_lists() {
        assert_eq!(parse_f16_operand("-2"), Some(0xC000));
        assert_eq!(parse_f16_operand("1"), Some(0x3C00));
        assert_eq!(parse_f16_operand("nan"), Some(0x7E00));
        assert_eq!(parse_f16_operand("70000"), Some(0x7C00));
        assert_eq!(parse_f16_operand("6.1e-17"), Some(0x0000));
        assert_eq!(parse_f16_operand("0x3c00"), Some(0x7380), "integer fallback: 15360.0");
        assert_eq!(parse_f16_operand("0xffff"), Some(0xBC00), "read as signed: -1.0");
        assert_eq!(parse_f16_operand("1_0.5"), Some(half::f16::from_f64(10.5).to_bits()));
        // float() rejects "1__0"; the integer fallback removes every '_' and reads 10.
        assert_eq!(parse_f16_operand("1__0"), Some(half::f16::from_f64(10.0).to_bits()));
        assert_eq!(parse_f16_operand("0.3333"), Some(half::f16::from_f64(0.3333).to_bits()));
        assert_eq!(parse_f16_operand("infinity"), Some(0x7C00));
        assert_eq!(parse_f16_operand("-inf"), Some(0xFC00));
        assert_eq!(parse_f16_operand("abc"), None);
    }

    #[test]
    fn every_non_nan_half_prints_and_reparses() {
        for bits in 0..=u16::MAX {
            match f16_to_text(bits) {
                Some(t) => assert_eq!(parse_f16_operand(&t), Some(bits), "{bits:#06x} -> {t}"),
                None => assert!(f16::from_bits(bits).is_nan()),
            }
        }
    }
}
