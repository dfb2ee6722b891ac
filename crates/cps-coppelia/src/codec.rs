//! CBOR through one module (serde_cbor today; swapping the crate touches only this file),
//! with the lenient reading the protocol needs: integers where floats are expected, every
//! float width, text or byte strings, unknown tags unwrapped, an empty map where an array
//! of return values is expected.

use std::collections::BTreeMap;

pub use serde_cbor::Value;

/// What kind of value `v` is, in words (for error messages).
pub fn describe(v: &Value) -> &'static str {
    match untag(v) {
        Value::Null => "nothing",
        Value::Bool(_) => "a boolean",
        Value::Integer(_) => "an integer",
        Value::Float(_) => "a number",
        Value::Bytes(_) => "bytes",
        Value::Text(_) => "text",
        Value::Array(_) => "a table",
        Value::Map(_) => "a map",
        _ => "an unknown value",
    }
}

/// Decodes one CBOR item; hostile input gives an error, never a panic (the decoder limits
/// recursion depth).
pub fn decode(bytes: &[u8]) -> Result<Value, String> {
    serde_cbor::from_slice(bytes).map_err(|e| format!("invalid CBOR: {e}"))
}

/// Encodes a value (floats in their shortest lossless width, as CoppeliaSim does).
pub fn encode(value: &Value) -> Vec<u8> {
    serde_cbor::to_vec(value).expect("a CBOR value always encodes")
}

/// Removes any number of tags around a value.
pub fn untag(mut v: &Value) -> &Value {
    while let Value::Tag(_, inner) = v {
        v = inner;
    }
    v
}

/// A number as f64 (ints and floats of any width).
pub fn as_f64(v: &Value) -> Option<f64> {
    match untag(v) {
        Value::Float(f) => Some(*f),
        Value::Integer(i) => Some(*i as f64),
        _ => None,
    }
}

/// An integer (floats with an integral value are accepted).
pub fn as_i64(v: &Value) -> Option<i64> {
    match untag(v) {
        Value::Integer(i) => i64::try_from(*i).ok(),
        Value::Float(f) if f.fract() == 0.0 && f.abs() < 9e15 => Some(*f as i64),
        _ => None,
    }
}

/// Text, or a byte string holding UTF-8.
pub fn as_text(v: &Value) -> Option<String> {
    match untag(v) {
        Value::Text(s) => Some(s.clone()),
        Value::Bytes(b) => String::from_utf8(b.clone()).ok(),
        _ => None,
    }
}

/// A boolean.
pub fn as_bool(v: &Value) -> Option<bool> {
    match untag(v) {
        Value::Bool(b) => Some(*b),
        _ => None,
    }
}

/// An array of numbers.
pub fn as_f64_vec(v: &Value) -> Option<Vec<f64>> {
    match untag(v) {
        Value::Array(a) => a.iter().map(as_f64).collect(),
        _ => None,
    }
}

/// A list of values: an array, or an empty map (a Lua empty table), or nothing.
pub fn as_list(v: Option<&Value>) -> Option<Vec<Value>> {
    match v.map(untag) {
        None | Some(Value::Null) => Some(Vec::new()),
        Some(Value::Array(a)) => Some(a.clone()),
        Some(Value::Map(m)) if m.is_empty() => Some(Vec::new()),
        _ => None,
    }
}

/// The value under a text key of a map (keys sent as byte strings are matched too).
pub fn get<'a>(map: &'a Value, key: &str) -> Option<&'a Value> {
    match untag(map) {
        Value::Map(m) => m
            .get(&Value::Text(key.into()))
            .or_else(|| m.get(&Value::Bytes(key.as_bytes().to_vec()))),
        _ => None,
    }
}

/// A map with text keys.
pub fn map(entries: impl IntoIterator<Item = (&'static str, Value)>) -> Value {
    Value::Map(
        entries
            .into_iter()
            .map(|(k, v)| (Value::Text(k.into()), v))
            .collect::<BTreeMap<_, _>>(),
    )
}

/// Text.
pub fn text(s: &str) -> Value {
    Value::Text(s.into())
}

/// An array of floats.
pub fn floats(v: &[f64]) -> Value {
    Value::Array(v.iter().map(|x| Value::Float(*x)).collect())
}

/// An integer.
pub fn int(i: i64) -> Value {
    Value::Integer(i128::from(i))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bytes captured from the official client and CoppeliaSim-style replies
    /// (docs/coppelia-protocol.md §7).
    #[test]
    fn decodes_the_captured_replies_leniently() {
        let hex = |s: &str| -> Vec<u8> {
            (0..s.len())
                .step_by(2)
                .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
                .collect()
        };
        // {"ret": {}} — a void function.
        let v = decode(&hex("a163726574a0")).unwrap();
        assert_eq!(as_list(get(&v, "ret")), Some(vec![]));
        // {"ret": [[f16 0.0, f16 0.0, f64 0.7]]}
        let v = decode(&hex("a1637265748183f90000f90000fb3fe6666666666666")).unwrap();
        let ret = as_list(get(&v, "ret")).unwrap();
        assert_eq!(as_f64_vec(&ret[0]), Some(vec![0.0, 0.0, 0.7]));
        // {"ret": [16]} — an int handle; {"ret": [f16 0.5]}
        let v = decode(&hex("a1637265748110")).unwrap();
        assert_eq!(as_i64(&as_list(get(&v, "ret")).unwrap()[0]), Some(16));
        let v = decode(&hex("a16372657481f93800")).unwrap();
        assert_eq!(as_f64(&as_list(get(&v, "ret")).unwrap()[0]), Some(0.5));
        // {"args": {}, "func": "_*wait*_"}
        let v = decode(&hex("a26461726773a06466756e63685f2a776169742a5f")).unwrap();
        assert_eq!(
            as_text(get(&v, "func").unwrap()).as_deref(),
            Some("_*wait*_")
        );
        assert_eq!(as_list(get(&v, "args")), Some(vec![]));
        // Ints for floats, bytes for text, tags unwrapped.
        assert_eq!(as_f64(&int(3)), Some(3.0));
        assert_eq!(
            as_text(&Value::Bytes(b"sim".to_vec())).as_deref(),
            Some("sim")
        );
        assert_eq!(
            as_f64(&Value::Tag(86, Box::new(Value::Float(1.5)))),
            Some(1.5)
        );
        assert!(decode(&hex("a1")).is_err());
    }

    #[test]
    fn encodes_floats_in_their_shortest_width() {
        assert_eq!(encode(&Value::Float(0.5)), vec![0xf9, 0x38, 0x00]);
        assert_eq!(encode(&Value::Float(0.7))[0], 0xfb);
        let v = map([("ret", Value::Map(BTreeMap::new()))]);
        assert_eq!(encode(&v), vec![0xa1, 0x63, b'r', b'e', b't', 0xa0]);
    }
}
