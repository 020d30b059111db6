//! Bounds on the work of the loaders: file sizes, vertices per zone, radio map rows, and a
//! bounded, UTF-8-checked file reader.

use std::io::Read;
use std::path::Path;

use crate::error::{EngineError, Result};

/// The largest site file the loader reads, bytes (16 MiB; a large site is a few hundred kB).
pub const MAX_SITE_BYTES: u64 = 16 << 20;

/// The largest radio map file the loader reads, bytes (256 MiB: UJIIndoorLoc's 19 937 training
/// records with 520 access points written as a radio map take about 21 MB).
pub const MAX_RADIO_MAP_BYTES: u64 = 256 << 20;

/// The most reference points (rows) a radio map may have (each scan is matched against every
/// one of them).
pub const MAX_RADIO_MAP_ROWS: usize = 1_000_000;

/// The most vertices a polygon zone may have (checking that it does not cross itself takes
/// time quadratic in this).
pub const MAX_ZONE_VERTICES: usize = 10_000;

/// Reads a text file of at most `max_bytes` bytes (through `take`, so a device such as
/// `/dev/urandom` or a growing file cannot make it read forever).
///
/// `what` names the file's role in errors (`site`, `radio map`).
///
/// # Errors
/// [`EngineError::Parse`] naming the file (as `path` displays) with line 0 when it cannot be
/// opened or read or is larger than `max_bytes`; with the line of the first bad byte when it is
/// not UTF-8 text (a binary file).
///
/// # Examples
/// ```
/// use rtls_engine::site::{read_text_file, MAX_SITE_BYTES};
///
/// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/site.toml");
/// assert!(read_text_file(path.as_ref(), MAX_SITE_BYTES, "site").is_ok());
/// let error = read_text_file(path.as_ref(), 100, "site").unwrap_err();
/// assert!(error.to_string().contains("larger than the 100-byte limit"));
/// ```
pub fn read_text_file(path: &Path, max_bytes: u64, what: &str) -> Result<String> {
    let name = path.display().to_string();
    let error = |line: usize, reason: String| EngineError::Parse {
        file: name.clone(),
        line,
        field: "-".into(),
        reason,
    };
    let file = std::fs::File::open(path).map_err(|e| error(0, format!("cannot open the {what} file: {e}")))?;
    let mut bytes = Vec::new();
    file.take(max_bytes.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| error(0, format!("cannot read the {what} file: {e}")))?;
    if bytes.len() as u64 > max_bytes {
        return Err(error(
            0,
            format!("the {what} file is larger than the {max_bytes}-byte limit; is it the right file?"),
        ));
    }
    text_of(bytes, &name, what)
}

/// The bytes as UTF-8 text, or an error at the line of the first invalid byte.
pub(crate) fn text_of(bytes: Vec<u8>, file: &str, what: &str) -> Result<String> {
    String::from_utf8(bytes).map_err(|e| {
        let valid = e.utf8_error().valid_up_to();
        let bytes = e.as_bytes();
        let line = bytes[..valid].iter().filter(|&&b| b == b'\n').count() + 1;
        let column = valid - bytes[..valid].iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1) + 1;
        EngineError::Parse {
            file: file.to_string(),
            line,
            field: "-".into(),
            reason: format!("byte {column} of the line is not UTF-8; a {what} file is text (is it a binary file?)"),
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn binary_and_oversized_input_is_refused_with_its_line() {
        let error = text_of(b"a = 1\nb = \xff\n".to_vec(), "x.toml", "site").unwrap_err();
        assert_eq!(
            error.to_string(),
            "x.toml:2: field `-`: byte 5 of the line is not UTF-8; a site file is text (is it a binary file?)"
        );
        // a device that never ends is read up to the limit only
        if Path::new("/dev/urandom").exists() {
            let error = read_text_file(Path::new("/dev/urandom"), 1 << 16, "radio map").unwrap_err();
            assert!(matches!(error, EngineError::Parse { .. }), "{error}");
        }
        let missing = read_text_file(Path::new("/nonexistent/site.toml"), 10, "site").unwrap_err();
        assert!(missing
            .to_string()
            .starts_with("/nonexistent/site.toml:0: field `-`: cannot open the site file"));
    }
}
