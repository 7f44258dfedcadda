//! JSON pointers (RFC 6901) and the small readings of glTF values that the loader and its
//! conformance checks share.

use serde_json::Value;

/// `/a/0/b` from parts.
pub(crate) fn ptr(parts: &[&dyn std::fmt::Display]) -> String {
    parts.iter().map(|p| format!("/{}", esc(&p.to_string()))).collect()
}

/// A JSON object key as a JSON pointer token (RFC 6901 §3: `~` as `~0`, `/` as `~1`).
pub(crate) fn esc(key: &str) -> String {
    key.replace('~', "~0").replace('/', "~1")
}

/// A JSON number that is a non-negative integer (`3` or `3.0`).
pub(crate) fn as_uint(x: &Value) -> Option<u64> {
    x.as_u64().or_else(|| x.as_f64().filter(|f| *f >= 0.0 && f.fract() == 0.0 && *f < 9.0e15).map(|f| f as u64))
}

/// Whether accessor `a` has a known element type and component type (one that does not is
/// an error only where it is read).
pub(crate) fn known_layout(a: &Value) -> bool {
    a.get("type").and_then(Value::as_str).is_some_and(|t| ["SCALAR", "VEC2", "VEC3", "VEC4", "MAT2", "MAT3", "MAT4"].contains(&t))
        && a.get("componentType").and_then(as_uint).and_then(comp_size).is_some()
}

pub(crate) fn comp_size(c: u64) -> Option<usize> {
    match c {
        5120 | 5121 => Some(1),
        5122 | 5123 => Some(2),
        5125 | 5126 => Some(4),
        _ => None,
    }
}

/// How far from 1 a unit vector's or quaternion's length may be (the validator's bound).
pub(crate) const UNIT_TOLERANCE: f32 = 5e-4;
