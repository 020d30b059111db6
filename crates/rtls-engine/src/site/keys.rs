//! Maps between byte offsets / line numbers of a TOML text and key paths such as
//! `readers[3].position_m`, for error messages. A light line scanner, not a TOML parser: it
//! understands table headers, array-of-tables headers, `key = value` lines and values that span
//! several lines; keys inside inline tables map to the line of their enclosing key.

use std::collections::HashMap;

/// What one physical line is, for locating keys (a continuation line of a multi-line value
/// carries the key that opened the value).
#[derive(Debug, Clone, PartialEq)]
struct Scanned {
    /// Resolved table path in force (`zones[1].shape`, or empty for the root).
    table: String,
    /// The key defined on this line, if any (`position_m`).
    key: Option<String>,
}

impl Scanned {
    fn path(&self) -> String {
        match (&self.key, self.table.is_empty()) {
            (Some(key), true) => key.clone(),
            (Some(key), false) => format!("{}.{key}", self.table),
            (None, _) => self.table.clone(),
        }
    }
}

fn unquote(segment: &str) -> String {
    segment.trim().trim_matches(|c| c == '"' || c == '\'').to_string()
}

/// Resolves a dotted table name, appending the current index of every array of tables.
fn resolve(segments: &[String], arrays: &HashMap<String, usize>) -> String {
    let mut out = String::new();
    for segment in segments {
        if !out.is_empty() {
            out.push('.');
        }
        out.push_str(segment);
        if let Some(n) = arrays.get(&out) {
            out.push_str(&format!("[{}]", n.saturating_sub(1)));
        }
    }
    out
}

/// Change of bracket depth over a value, ignoring strings and comments.
fn depth_change(value: &str) -> i64 {
    let mut depth = 0;
    let mut quote: Option<char> = None;
    let mut escaped = false;
    for c in value.chars() {
        match quote {
            Some(q) => {
                if escaped {
                    escaped = false;
                } else if c == '\\' && q == '"' {
                    escaped = true;
                } else if c == q {
                    quote = None;
                }
            }
            None => match c {
                '"' | '\'' => quote = Some(c),
                '[' | '{' => depth += 1,
                ']' | '}' => depth -= 1,
                '#' => break,
                _ => {}
            },
        }
    }
    depth
}

fn scan(text: &str) -> Vec<Scanned> {
    let mut arrays: HashMap<String, usize> = HashMap::new();
    let mut table = String::new();
    let mut depth = 0_i64;
    let mut continued: Option<String> = None;
    let mut lines = Vec::new();
    for raw in text.lines() {
        let line = raw.trim();
        if depth > 0 {
            // a value spanning several lines belongs to the key that opened it
            depth += depth_change(line);
            lines.push(Scanned {
                table: table.clone(),
                key: continued.clone(),
            });
            continue;
        }
        let mut key = None;
        if let Some(rest) = line.strip_prefix("[[") {
            let name: Vec<String> = rest.split("]]").next().unwrap_or("").split('.').map(unquote).collect();
            let (last, parents) = name
                .split_last()
                .map_or((String::new(), &[][..]), |(l, p)| (l.clone(), p));
            let parent = resolve(parents, &arrays);
            let full = if parent.is_empty() {
                last
            } else {
                format!("{parent}.{last}")
            };
            *arrays.entry(full).or_insert(0) += 1;
            table = resolve(&name, &arrays);
        } else if let Some(rest) = line.strip_prefix('[') {
            let name: Vec<String> = rest.split(']').next().unwrap_or("").split('.').map(unquote).collect();
            table = resolve(&name, &arrays);
        } else if !line.starts_with('#') {
            if let Some((k, value)) = line.split_once('=') {
                key = Some(k.split('.').map(unquote).collect::<Vec<_>>().join("."));
                depth = depth_change(value).max(0);
                continued.clone_from(&key);
            }
        }
        lines.push(Scanned {
            table: table.clone(),
            key,
        });
    }
    lines
}

/// The 1-based line and the key path at a byte offset.
pub(super) fn path_at(text: &str, offset: usize) -> (usize, String) {
    let offset = offset.min(text.len());
    let line = text.as_bytes()[..offset].iter().filter(|&&b| b == b'\n').count() + 1;
    let path = scan(text).get(line - 1).map(Scanned::path).unwrap_or_default();
    (line, path)
}

/// The 1-based line that defines `path` or, failing that, its nearest enclosing key or table;
/// 0 when none is found.
pub(super) fn line_of(text: &str, path: &str) -> usize {
    let lines = scan(text);
    let mut candidate = path.to_string();
    loop {
        if let Some(i) = lines.iter().position(|s| s.path() == candidate) {
            return i + 1;
        }
        // drop the last `.key` or `[index]`
        let cut = match (candidate.rfind('.'), candidate.rfind('[')) {
            (Some(d), Some(b)) => d.max(b),
            (Some(d), None) => d,
            (None, Some(b)) => b,
            (None, None) => return 0,
        };
        candidate.truncate(cut);
        if candidate.is_empty() {
            return 0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = r#"name = "x"
[[readers]]
id = "a"
[[readers]]
id = "b"   # the second
position_m = [
  1.0,
  2.0,
]
radio = { range = { range_std_m = 0.1, bias_m = 0.0 } }
[[zones]]
id = "z"
[zones.shape]
type = "box"
[tracker]
initiation = { confirm_updates = 2, within_s = 3.0 }
"#;

    #[test]
    fn paths_resolve_to_lines() {
        assert_eq!(line_of(TEXT, "name"), 1);
        assert_eq!(line_of(TEXT, "readers[1].id"), 5);
        assert_eq!(line_of(TEXT, "readers[1].position_m"), 6);
        assert_eq!(line_of(TEXT, "readers[1].radio.range.range_std_m"), 10);
        assert_eq!(line_of(TEXT, "readers[0].position_m"), 2); // absent key: its table
        assert_eq!(line_of(TEXT, "zones[0].shape.type"), 14);
        assert_eq!(line_of(TEXT, "zones[0].shape.min_m"), 13);
        assert_eq!(line_of(TEXT, "tracker.initiation.within_s"), 16);
        assert_eq!(line_of(TEXT, "floors[0].id"), 0);
    }

    #[test]
    fn offsets_resolve_to_paths() {
        let at = |needle: &str| path_at(TEXT, TEXT.find(needle).unwrap());
        assert_eq!(at("\"b\""), (5, "readers[1].id".to_string()));
        assert_eq!(at("2.0,"), (8, "readers[1].position_m".to_string())); // a continuation line
        assert_eq!(at("type"), (14, "zones[0].shape.type".to_string()));
        assert_eq!(path_at(TEXT, usize::MAX).0, TEXT.lines().count() + 1);
    }
}
