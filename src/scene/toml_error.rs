//! Reducing a toml/serde error (multi-line, with a caret display) to the scene's one-line form:
//! the key path (found by a light scan of the TOML text around the error's span), the message
//! and the line number.

use std::collections::BTreeMap;

/// Turns a toml error (multi-line, with a caret display) into one line naming the key path and
/// the line number.
pub(super) fn toml_error(text: &str, e: &toml::de::Error) -> String {
    let msg =
        e.message().lines().map(str::trim).filter(|l| !l.is_empty()).collect::<Vec<_>>().join("; ");
    let span = e.span().unwrap_or(0..0);
    let loc = locate(text, span.start);
    let at = format!(" (line {})", loc.line);

    let is_data = [
        "unknown field",
        "missing field",
        "invalid type",
        "invalid value",
        "unknown variant",
        "invalid length",
        "duplicate field",
    ]
    .iter()
    .any(|p| msg.starts_with(p));
    if !is_data {
        return format!("invalid TOML: {msg} (line {}, column {})", loc.line, loc.column);
    }

    let spanned = text.get(span.clone()).unwrap_or("");
    let whole_doc = span.start == 0 && (span.end == 0 || span.end >= text.trim_end().len());
    // Key path of the value the span points at.
    let value_path = || -> String {
        if whole_doc {
            return String::new();
        }
        if loc.on_header {
            return loc.table.clone();
        }
        let mut parts: Vec<String> = Vec::new();
        if !loc.table.is_empty() {
            parts.push(loc.table.clone());
        }
        parts.extend(loc.inline.iter().cloned());
        match &loc.key {
            Some(k) => parts.push(k.clone()),
            None => {
                if let Some(k) = &loc.previous_key {
                    parts.push(k.clone());
                }
            }
        }
        parts.join(".")
    };
    let join = |a: &str, b: &str| {
        if a.is_empty() {
            b.to_string()
        } else {
            format!("{a}.{b}")
        }
    };

    if let Some(rest) = msg.strip_prefix("unknown field ") {
        let (field, allowed) = split_expected(rest);
        let base = if loc.on_header {
            // `[unknown]` or `[known.unknown]`: the parent of the header's table.
            let t = loc.table.split('[').next().unwrap_or("");
            t.rsplit_once('.').map(|(p, _)| p.to_string()).unwrap_or_default()
        } else if spanned.trim_matches(|c| c == '"' || c == '\'') == field {
            // The span is the key itself.
            let mut parts: Vec<String> = Vec::new();
            if !loc.table.is_empty() {
                parts.push(loc.table.clone());
            }
            parts.extend(loc.inline.iter().cloned());
            parts.join(".")
        } else {
            value_path()
        };
        return format!("unknown key \"{}\" (allowed: {allowed}){at}", join(&base, &field));
    }
    if let Some(rest) = msg.strip_prefix("missing field ") {
        let field = rest.trim_matches('`');
        return format!("missing key \"{}\"{at}", join(&value_path(), field));
    }
    if let Some(rest) = msg.strip_prefix("unknown variant ") {
        let (v, allowed) = split_expected(rest);
        let path = value_path();
        let path = if path.is_empty() { "value".into() } else { path };
        return format!("{path} = \"{v}\" is not allowed (allowed: {allowed}){at}");
    }
    if let Some(rest) = msg.strip_prefix("invalid type: ") {
        let path = value_path();
        let rest = rest
            .replace("expected f64", "expected a number")
            .replace("expected i64", "expected an integer");
        return format!("{path} has the wrong type: {rest}{at}");
    }
    let path = value_path();
    if path.is_empty() {
        format!("{msg}{at}")
    } else {
        format!("{path}: {msg}{at}")
    }
}

/// "`f`, expected one of `a`, `b`" -> ("f", "a, b").
fn split_expected(rest: &str) -> (String, String) {
    let (name, tail) = rest.split_once(", expected").unwrap_or((rest, ""));
    let name = name.trim().trim_matches('`').to_string();
    let tail = tail.trim();
    let tail = tail.strip_prefix("one of").unwrap_or(tail);
    let allowed = if tail.is_empty() || rest.contains("there are no fields") {
        "none".to_string()
    } else {
        tail.replace(" or ", ", ")
            .split(',')
            .map(|s| s.trim().trim_matches('`'))
            .filter(|s| !s.is_empty())
            .collect::<Vec<_>>()
            .join(", ")
    };
    (name, allowed)
}

/// Where a byte offset is in the TOML text, as far as a light scan can tell.
#[derive(Debug, Default)]
struct Location {
    /// 1-based.
    line: usize,
    /// 1-based, in characters.
    column: usize,
    /// Current table path (`material`, `dirichlet[1]`), empty at the root.
    table: String,
    /// The line is a table header.
    on_header: bool,
    /// Enclosing inline-table keys on this line, outermost first.
    inline: Vec<String>,
    /// The key whose value the offset is in (on this line).
    key: Option<String>,
    /// If no key is on this line (multi-line array): the last key that started a line above.
    previous_key: Option<String>,
}

fn locate(text: &str, offset: usize) -> Location {
    let offset = offset.min(text.len());
    let mut loc = Location { line: 1, column: 1, ..Default::default() };
    let mut counts: BTreeMap<String, usize> = BTreeMap::new();
    let mut line_start = 0;
    for (n, line) in text.split_inclusive('\n').enumerate() {
        let line_end = line_start + line.len();
        let last = line_end > offset || line_end == text.len();
        let trimmed = line.trim_start();
        let header = trimmed.starts_with('[');
        if header {
            let body = strip_comment(trimmed).trim();
            if let Some(inner) = body.strip_prefix("[[") {
                let name = inner.trim_end_matches(']').trim().to_string();
                let c = counts.entry(name.clone()).or_insert(0);
                loc.table = format!("{name}[{c}]");
                *c += 1;
            } else {
                loc.table = body.trim_start_matches('[').trim_end_matches(']').trim().to_string();
            }
            loc.previous_key = None;
        } else if let Some(k) = leading_key(trimmed) {
            if !last {
                loc.previous_key = Some(k);
            }
        }
        if last {
            loc.line = n + 1;
            let prefix = &text[line_start..offset.max(line_start).min(line_end)];
            loc.column = prefix.chars().count() + 1;
            loc.on_header = header;
            if !header {
                let (inline, key) = scan_keys(prefix);
                loc.inline = inline;
                loc.key = key;
            }
            break;
        }
        line_start = line_end;
    }
    loc
}

fn strip_comment(s: &str) -> &str {
    // Good enough for headers and keys (no '#' inside quoted header names).
    s.split('#').next().unwrap_or(s)
}

/// `key = ...` at the start of a line -> `key`.
fn leading_key(s: &str) -> Option<String> {
    let (k, _) = s.split_once('=')?;
    let k = k.trim();
    if k.is_empty() || !k.chars().all(|c| c.is_ascii_alphanumeric() || "_-.\"' ".contains(c)) {
        return None;
    }
    Some(k.replace(['"', '\'', ' '], ""))
}

/// Scans a line prefix for `key =` assignments and inline-table braces; returns the enclosing
/// inline-table keys and the key whose value the prefix ends in.
fn scan_keys(prefix: &str) -> (Vec<String>, Option<String>) {
    let mut stack: Vec<String> = Vec::new();
    let mut key: Option<String> = None;
    let mut word = String::new();
    let mut quote: Option<char> = None;
    for c in prefix.chars() {
        if let Some(q) = quote {
            if c == q {
                quote = None;
            }
            continue;
        }
        match c {
            '"' | '\'' => {
                quote = Some(c);
                word.clear();
            }
            '#' => break,
            '=' => {
                if !word.is_empty() {
                    key = Some(std::mem::take(&mut word));
                }
            }
            '{' => {
                if let Some(k) = key.take() {
                    stack.push(k);
                }
                word.clear();
            }
            '}' => {
                key = stack.pop();
                word.clear();
            }
            '[' | ']' => {}
            c if c.is_ascii_alphanumeric() || c == '_' || c == '-' || c == '.' => word.push(c),
            c if c.is_whitespace() => {}
            _ => word.clear(),
        }
    }
    (stack, key)
}
