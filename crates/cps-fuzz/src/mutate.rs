//! Input generators: grammar-aware mutations of valid inputs (one number, string, line,
//! table or value changed the way a hostile or careless file would) and raw byte mutations.

use rand::Rng;
use rand::seq::IndexedRandom;
use rand_chacha::ChaCha8Rng;

/// Numbers that break naive code: zero and signs, the extremes of f64 and of the integer
/// types, non-finite spellings, huge counts, values just off the usual ones.
pub const HOSTILE_NUMBERS: &[&str] = &[
    "0",
    "-0",
    "-1",
    "1",
    "2",
    "3",
    "0.5",
    "-0.5",
    "1e-300",
    "-1e-300",
    "5e-324",
    "1e300",
    "-1e300",
    "1.7976931348623157e308",
    "nan",
    "inf",
    "-inf",
    "NaN",
    "1e6",
    "1e9",
    "100000000",
    "4294967296",
    "2147483648",
    "9223372036854775807",
    "-9223372036854775808",
    "18446744073709551615",
    "18446744073709551616",
    "1e-9",
    "1e-12",
    "0.001",
    "10000",
    "100000",
];

/// Strings that break naive code.
const HOSTILE_STRINGS: &[&str] = &[
    "",
    " ",
    "..",
    "../../../../etc/passwd",
    "/dev/zero",
    "/dev/stdin",
    "\u{0}",
    "é☃\u{202e}",
    "tcp://256.256.256.256:99999",
    "tcp://[::1]:0",
    "tcp://127.0.0.1:1",
    "auto",
    "raw",
    "nan",
];

/// Where the numbers of a text are: byte ranges of numeric literals (with sign, fraction,
/// exponent, underscores, and the words inf/nan).
fn numbers(text: &str) -> Vec<(usize, usize)> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let starts = b[i].is_ascii_digit()
            || ((b[i] == b'-' || b[i] == b'+' || b[i] == b'.')
                && b.get(i + 1).is_some_and(|c| c.is_ascii_digit()));
        let word_before = i > 0 && (b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_');
        if starts && !word_before {
            let s = i;
            i += 1;
            while i < b.len()
                && (b[i].is_ascii_digit()
                    || matches!(b[i], b'.' | b'e' | b'E' | b'_')
                    || ((b[i] == b'-' || b[i] == b'+') && matches!(b[i - 1], b'e' | b'E')))
            {
                i += 1;
            }
            out.push((s, i));
        } else {
            i += 1;
        }
    }
    out
}

/// Byte ranges of double-quoted strings (their content).
fn strings(text: &str) -> Vec<(usize, usize)> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'"' {
            let s = i + 1;
            let mut j = s;
            while j < b.len() && b[j] != b'"' && b[j] != b'\n' {
                j += 1;
            }
            if j < b.len() && b[j] == b'"' {
                out.push((s, j));
            }
            i = j + 1;
        } else {
            i += 1;
        }
    }
    out
}

fn splice(text: &str, (s, e): (usize, usize), with: &str) -> String {
    format!("{}{}{}", &text[..s], with, &text[e..])
}

/// One grammar-aware change to a text input.
pub fn mutate_text(text: &str, rng: &mut ChaCha8Rng, others: &[&str]) -> String {
    let lines: Vec<&str> = text.lines().collect();
    match rng.random_range(0..12) {
        // A number becomes a hostile one (the most common and most fruitful change).
        0..=4 => {
            let spots = numbers(text);
            match spots.choose(rng) {
                Some(&spot) => splice(text, spot, HOSTILE_NUMBERS.choose(rng).unwrap()),
                None => text.to_string(),
            }
        }
        // A string becomes a hostile one, or a very long one.
        5 => {
            let spots = strings(text);
            match spots.choose(rng) {
                Some(&spot) if rng.random_bool(0.2) => {
                    splice(text, spot, &"x".repeat(rng.random_range(1000..100_000)))
                }
                Some(&spot) => splice(text, spot, HOSTILE_STRINGS.choose(rng).unwrap()),
                None => text.to_string(),
            }
        }
        // A line disappears.
        6 if !lines.is_empty() => {
            let k = rng.random_range(0..lines.len());
            lines
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != k)
                .map(|(_, l)| *l)
                .collect::<Vec<_>>()
                .join("\n")
        }
        // A line or a block of lines is repeated (duplicate keys, tables, rows).
        7 if !lines.is_empty() => {
            let k = rng.random_range(0..lines.len());
            let n = rng.random_range(1..=(lines.len() - k).min(12));
            let times = if rng.random_bool(0.1) { 1000 } else { 1 };
            let mut out: Vec<&str> = lines[..k + n].to_vec();
            for _ in 0..times {
                out.extend_from_slice(&lines[k..k + n]);
            }
            out.extend_from_slice(&lines[k + n..]);
            out.join("\n")
        }
        // A number becomes another type.
        8 => {
            let spots = numbers(text);
            let with = ["\"text\"", "true", "[]", "{}", "[1, 2]", "[[1]]", "\"\""]
                .choose(rng)
                .unwrap();
            match spots.choose(rng) {
                Some(&spot) => splice(text, spot, with),
                None => text.to_string(),
            }
        }
        // A value is nested very deeply.
        9 => {
            let spots = numbers(text);
            let depth = *[10usize, 100, 1000, 50_000].choose(rng).unwrap();
            let (open, close) = match rng.random_range(0..3) {
                0 => ("[", "]"),
                1 => ("{a=", "}"),
                _ => ("<a>", "</a>"),
            };
            match spots.choose(rng) {
                Some(&(s, e)) => splice(
                    text,
                    (s, e),
                    &format!(
                        "{}{}{}",
                        open.repeat(depth),
                        &text[s..e],
                        close.repeat(depth)
                    ),
                ),
                None => format!("{}{}", open.repeat(depth), close.repeat(depth)),
            }
        }
        // A piece of another valid input is spliced in.
        10 if !others.is_empty() => {
            let other = others.choose(rng).unwrap();
            let cut = |t: &str, rng: &mut ChaCha8Rng| {
                let mut k = rng.random_range(0..=t.len());
                while !t.is_char_boundary(k) {
                    k -= 1;
                }
                k
            };
            let (a, b) = (cut(text, rng), cut(other, rng));
            format!("{}{}", &text[..a], &other[b..])
        }
        // The text is cut short.
        _ => {
            let mut k = rng.random_range(0..=text.len());
            while !text.is_char_boundary(k) {
                k -= 1;
            }
            text[..k].to_string()
        }
    }
}

/// One raw byte change.
pub fn mutate_bytes(bytes: &[u8], rng: &mut ChaCha8Rng) -> Vec<u8> {
    let mut b = bytes.to_vec();
    match rng.random_range(0..5) {
        0 if !b.is_empty() => {
            for _ in 0..rng.random_range(1..8) {
                let k = rng.random_range(0..b.len());
                b[k] ^= 1 << rng.random_range(0..8);
            }
        }
        1 if !b.is_empty() => {
            let k = rng.random_range(0..b.len());
            b[k] = rng.random();
        }
        2 => {
            let k = rng.random_range(0..=b.len());
            let extra: Vec<u8> = (0..rng.random_range(1..32)).map(|_| rng.random()).collect();
            b.splice(k..k, extra);
        }
        3 => b.truncate(rng.random_range(0..=b.len())),
        _ => {
            b = (0..rng.random_range(0..256))
                .map(|_| rng.random())
                .collect()
        }
    }
    b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_and_strings_are_found() {
        let t = "a = 1.5e-3\nb = [-2, 3_000]\nname = \"x\" # 7\nalpha_z = 25";
        let found: Vec<&str> = numbers(t).iter().map(|&(s, e)| &t[s..e]).collect();
        assert_eq!(found, ["1.5e-3", "-2", "3_000", "7", "25"]);
        let s: Vec<&str> = strings(t).iter().map(|&(s, e)| &t[s..e]).collect();
        assert_eq!(s, ["x"]);
    }
}
