//! The part of XML robot descriptions use, read into a tree of elements with their
//! attributes, text and lines: URDF, SRDF and the COLLADA meshes robot descriptions name
//! all read through it.
//!
//! ```
//! let root = cps_kinematics::xml::parse_xml("<robot name='r'>\n  <a>1 2 3</a>\n</robot>")?;
//! assert_eq!(root.attr("name"), Some("r"));
//! let a = root.child("a").unwrap();
//! assert_eq!((a.text().trim(), a.line()), ("1 2 3", 2));
//! # Ok::<(), String>(())
//! ```

/// How deeply elements may nest (`MAX_URDF_DEPTH` for URDF).
pub const MAX_DEPTH: usize = 64;

/// An XML element: its name, attributes, child elements, its own text (the character data
/// directly inside it, as written) and the line it starts on.
#[derive(Debug)]
pub struct Element {
    pub(crate) name: String,
    attrs: Vec<(String, String)>,
    pub(crate) children: Vec<Element>,
    pub(crate) line: usize,
    text: String,
}

impl Element {
    /// Its name (with any namespace prefix, as written).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The line its start tag is on.
    pub fn line(&self) -> usize {
        self.line
    }

    /// Its text: the character data directly inside it, entities not expanded.
    pub fn text(&self) -> &str {
        &self.text
    }

    /// Its attribute `key`, entities expanded.
    pub fn attr(&self, key: &str) -> Option<&str> {
        self.attrs
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }

    /// Its first child named `name`.
    pub fn child(&self, name: &str) -> Option<&Element> {
        self.children.iter().find(|c| c.name == name)
    }

    /// Its children named `name`, in order.
    pub fn children<'a>(&'a self, name: &'a str) -> impl Iterator<Item = &'a Element> + 'a {
        self.children.iter().filter(move |c| c.name == name)
    }

    /// Every child, in order.
    pub fn elements(&self) -> &[Element] {
        &self.children
    }
}

/// Reads the element tree of an XML document — the part of XML robot descriptions use:
/// elements, attributes in single or double quotes with the five named entities and
/// character references, comments, processing instructions, a DOCTYPE without an internal
/// subset, CDATA (skipped), text kept with the element it is in. Every error names the
/// line. No recursion: nesting is bounded by `MAX_URDF_DEPTH`.
pub fn parse_xml(xml: &str) -> Result<Element, String> {
    let b = xml.as_bytes();
    let mut i = if xml.starts_with('\u{feff}') { 3 } else { 0 };
    let line_at = |at: usize| 1 + b[..at.min(b.len())].iter().filter(|&&c| c == b'\n').count();
    let skip_to = |from: usize, pat: &str, what: &str| -> Result<usize, String> {
        xml[from..]
            .find(pat)
            .map(|p| from + p + pat.len())
            .ok_or_else(|| format!("line {}: {what} is not closed", line_at(from)))
    };
    let mut stack: Vec<Element> = Vec::new();
    let mut root: Option<Element> = None;
    while i < b.len() {
        if b[i] != b'<' {
            let end = xml[i..].find('<').map_or(b.len(), |p| i + p);
            let text = &xml[i..end];
            match stack.last_mut() {
                Some(open) => open.text.push_str(text),
                None if root.is_some() && !text.trim().is_empty() => {
                    let at = i + text.len() - text.trim_start().len();
                    return Err(format!("line {}: text after the root element", line_at(at)));
                }
                None => {}
            }
            i = end;
            continue;
        }
        let rest = &xml[i..];
        if rest.starts_with("<!--") {
            i = skip_to(i + 4, "-->", "a comment")?;
        } else if rest.starts_with("<![CDATA[") {
            i = skip_to(i + 9, "]]>", "a CDATA section")?;
        } else if rest.starts_with("<?") {
            i = skip_to(i + 2, "?>", "a processing instruction")?;
        } else if rest.starts_with("<!") {
            if rest[..rest.find('>').unwrap_or(rest.len())].contains('[') {
                return Err(format!(
                    "line {}: a DOCTYPE with an internal subset is not read",
                    line_at(i)
                ));
            }
            i = skip_to(i + 2, ">", "a declaration")?;
        } else if let Some(close) = rest.strip_prefix("</") {
            let end = close
                .find('>')
                .ok_or_else(|| format!("line {}: a closing tag is not closed", line_at(i)))?;
            let name = close[..end].trim();
            let Some(open) = stack.pop() else {
                return Err(format!("line {}: `</{name}>` closes nothing", line_at(i)));
            };
            if open.name != name {
                return Err(format!(
                    "line {}: `</{name}>` closes `<{}>` of line {}",
                    line_at(i),
                    open.name,
                    open.line
                ));
            }
            i += 2 + end + 1;
            attach(open, &mut stack, &mut root, line_at(i))?;
        } else {
            let line = line_at(i);
            let (element, closed, next) = start_tag(xml, i, line)?;
            i = next;
            if closed {
                attach(element, &mut stack, &mut root, line)?;
            } else {
                if stack.len() >= MAX_DEPTH {
                    return Err(format!(
                        "line {line}: elements are nested deeper than the {MAX_DEPTH} a robot description needs"
                    ));
                }
                stack.push(element);
            }
        }
    }
    if let Some(open) = stack.last() {
        return Err(format!(
            "`<{}>` of line {} is not closed",
            open.name, open.line
        ));
    }
    root.ok_or_else(|| "no element".to_string())
}

/// A finished element goes to its parent, or becomes the root (only one).
fn attach(
    element: Element,
    stack: &mut [Element],
    root: &mut Option<Element>,
    line: usize,
) -> Result<(), String> {
    match stack.last_mut() {
        Some(parent) => parent.children.push(element),
        None if root.is_none() => *root = Some(element),
        None => {
            return Err(format!(
                "line {line}: a second root element `<{}>`",
                element.name
            ));
        }
    }
    Ok(())
}

/// The start tag at `at` (`<name a="v" …>` or `…/>`): the element, whether it closed
/// itself, and where the text after it begins.
fn start_tag(xml: &str, at: usize, line: usize) -> Result<(Element, bool, usize), String> {
    let b = xml.as_bytes();
    let name_char = |c: u8| c.is_ascii_alphanumeric() || matches!(c, b'_' | b':' | b'-' | b'.');
    let mut i = at + 1;
    let start = i;
    while i < b.len() && name_char(b[i]) {
        i += 1;
    }
    if i == start {
        return Err(format!("line {line}: `<` starts no element"));
    }
    let mut element = Element {
        name: xml[start..i].to_string(),
        attrs: Vec::new(),
        children: Vec::new(),
        line,
        text: String::new(),
    };
    loop {
        while i < b.len() && b[i].is_ascii_whitespace() {
            i += 1;
        }
        match b.get(i) {
            None => return Err(format!("line {line}: `<{}` is not closed", element.name)),
            Some(b'>') => return Ok((element, false, i + 1)),
            Some(b'/') if b.get(i + 1) == Some(&b'>') => return Ok((element, true, i + 2)),
            _ => {}
        }
        let key_start = i;
        while i < b.len() && name_char(b[i]) {
            i += 1;
        }
        let key = &xml[key_start..i];
        while i < b.len() && b[i].is_ascii_whitespace() {
            i += 1;
        }
        if key.is_empty() || b.get(i) != Some(&b'=') {
            return Err(format!(
                "line {line}: a malformed attribute in `<{}>`",
                element.name
            ));
        }
        i += 1;
        while i < b.len() && b[i].is_ascii_whitespace() {
            i += 1;
        }
        let quote = match b.get(i) {
            Some(&q @ (b'"' | b'\'')) => q,
            _ => {
                return Err(format!(
                    "line {line}: the value of `{key}` in `<{}>` is not quoted",
                    element.name
                ));
            }
        };
        let value_start = i + 1;
        let len = b[value_start..]
            .iter()
            .position(|&c| c == quote)
            .ok_or_else(|| format!("line {line}: the value of `{key}` is not closed"))?;
        let value = unescape(&xml[value_start..value_start + len])
            .map_err(|e| format!("line {line}: `{key}`: {e}"))?;
        if element.attrs.iter().any(|(k, _)| k == key) {
            return Err(format!(
                "line {line}: `{key}` appears twice in `<{}>`",
                element.name
            ));
        }
        element.attrs.push((key.to_string(), value));
        i = value_start + len + 1;
    }
}

/// An attribute value with its entity and character references replaced.
fn unescape(v: &str) -> Result<String, String> {
    if !v.contains('&') {
        return Ok(v.to_string());
    }
    let mut out = String::with_capacity(v.len());
    let mut rest = v;
    while let Some(p) = rest.find('&') {
        out.push_str(&rest[..p]);
        let end = rest[p..].find(';').ok_or("a `&` starts no reference")?;
        let entity = &rest[p + 1..p + end];
        let c = match entity {
            "lt" => '<',
            "gt" => '>',
            "amp" => '&',
            "quot" => '"',
            "apos" => '\'',
            e if e.starts_with("#x") => u32::from_str_radix(&e[2..], 16)
                .ok()
                .and_then(char::from_u32)
                .ok_or_else(|| format!("`&{e};` is no character"))?,
            e if e.starts_with('#') => e[1..]
                .parse::<u32>()
                .ok()
                .and_then(char::from_u32)
                .ok_or_else(|| format!("`&{e};` is no character"))?,
            e => return Err(format!("`&{e};` is not an XML entity")),
        };
        out.push(c);
        rest = &rest[p + end + 1..];
    }
    out.push_str(rest);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_xml_reader_takes_what_descriptions_use_and_names_the_line_of_what_it_refuses() {
        let xml = "\u{feff}<?xml version=\"1.0\"?>\n<!DOCTYPE robot>\n<!-- a <comment> -->\n<robot name='a &amp; b &#x3C;&#62;'>\n  <link name=\"l\"><visual><geometry>text is passed over</geometry></visual></link>\n  <![CDATA[ <not/> ]]>\n  <xacro:property name=\"x\" value=\"1\"/>\n</robot>\n";
        let root = parse_xml(xml).unwrap();
        assert_eq!(root.name, "robot");
        assert_eq!(root.attr("name"), Some("a & b <>"));
        assert_eq!(root.children.len(), 2);
        assert_eq!(root.children[0].line, 5);
        for (bad, says) in [
            (
                "<robot><link></robot>",
                "line 1: `</robot>` closes `<link>` of line 1",
            ),
            (
                "<robot>\n<link name='a'>",
                "`<link>` of line 2 is not closed",
            ),
            ("<robot/><robot/>", "a second root element"),
            ("<robot name=a/>", "is not quoted"),
            ("<robot name='a' name='b'/>", "appears twice"),
            ("<robot name='&bogus;'/>", "is not an XML entity"),
            ("<!DOCTYPE r [<!ENTITY x 'y'>]><robot/>", "internal subset"),
            ("<robot/>junk", "text after the root element"),
            ("</robot>", "closes nothing"),
            ("<robot><!-- open", "a comment is not closed"),
            ("", "no element"),
        ] {
            let e = parse_xml(bad).unwrap_err();
            assert!(e.contains(says), "{bad}: {e}");
        }
    }
}
