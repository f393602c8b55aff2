//! Reading RON text for people: what a parse error means in words (with the nearest valid
//! name for a misspelt field) and where a dotted field path is written, so that every refusal
//! of `pipeline.ron` can point at its line and column.

use crate::error::LineCol;

/// A RON error in words, with the nearest valid name for a misspelt field or variant.
pub(super) fn describe_ron_error(code: &ron::Error) -> String {
    match code {
        ron::Error::NoSuchStructField {
            expected,
            found,
            outer,
        } => {
            let within = outer
                .as_ref()
                .map(|o| format!(" in `{o}`"))
                .unwrap_or_default();
            format!(
                "unknown field `{found}`{within}{}; expected one of {}",
                suggestion(found, expected),
                list(expected)
            )
        }
        ron::Error::NoSuchEnumVariant {
            expected, found, ..
        } => format!(
            "unknown value `{found}`{}; expected one of {}",
            suggestion(found, expected),
            list(expected)
        ),
        ron::Error::IntegerOutOfBounds => "integer out of range here; expected a whole number \
            of 0 or more (`walkers`, `standers` and `seed` are counts)"
            .to_string(),
        other => other.to_string(),
    }
}

fn suggestion(found: &str, expected: &[&str]) -> String {
    expected
        .iter()
        .map(|e| (strsim::levenshtein(found, e), *e))
        .filter(|(d, e)| *d <= (e.len().max(found.len()) / 2).max(2))
        .min()
        .map(|(_, e)| format!(" (did you mean `{e}`?)"))
        .unwrap_or_default()
}

fn list(names: &[&str]) -> String {
    names
        .iter()
        .map(|n| format!("`{n}`"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Finds a dotted field path in RON text by walking its keys in order: `scene.layers[2].path`
/// finds `scene:`, then the third `kind:` of a layer after it, then `path:` after that. Good
/// enough to point a person at the line; `None` when the field is not written (a default).
pub(super) fn locate_field(text: &str, field: &str) -> Option<LineCol> {
    let mut from = 0;
    for part in field.split('.') {
        let (key, index) = match part.split_once('[') {
            Some((key, rest)) => (key, rest.trim_end_matches(']').parse::<usize>().ok()),
            None => (part, None),
        };
        from = find_key(text, key, from)?;
        if let Some(index) = index {
            // Items of a list are told apart by their first key (`kind` for layers).
            let mut at = from;
            for _ in 0..=index {
                at = find_key(text, "kind", at + 1)?;
            }
            from = at;
        }
    }
    Some(line_col(text, from))
}

/// The byte offset of the next `key:` at or after `from`, skipping comments and strings.
fn find_key(text: &str, key: &str, from: usize) -> Option<usize> {
    let bytes = text.as_bytes();
    let mut i = from;
    while i < bytes.len() {
        match bytes[i] {
            b'/' if bytes.get(i + 1) == Some(&b'/') => {
                while i < bytes.len() && bytes[i] != b'\n' {
                    i += 1;
                }
            }
            b'"' => {
                i += 1;
                while i < bytes.len() && bytes[i] != b'"' {
                    i += if bytes[i] == b'\\' { 2 } else { 1 };
                }
                i += 1;
            }
            _ => {
                let is_ident = |b: u8| b.is_ascii_alphanumeric() || b == b'_';
                if text[i..].starts_with(key) && (i == 0 || !is_ident(bytes[i - 1])) {
                    let after = text[i + key.len()..].trim_start();
                    let boundary = bytes.get(i + key.len()).is_none_or(|b| !is_ident(*b));
                    if boundary && after.starts_with(':') {
                        return Some(i);
                    }
                }
                i += 1;
            }
        }
    }
    None
}

fn line_col(text: &str, offset: usize) -> LineCol {
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let col = before.len() - before.rfind('\n').map_or(0, |n| n + 1) + 1;
    LineCol { line, col }
}
