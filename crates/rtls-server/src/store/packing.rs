//! Byte-level helpers of the compacted blocks ([`super::history_blocks`],
//! [`super::log_blocks`]): LEB128 varints, zig-zag signed integers, and DEFLATE.
//!
//! A block's payload is one format byte followed by the DEFLATE stream (RFC 1951, through the
//! `flate2` crate's pure-Rust back end) of its fields.

use std::io::{Read, Write};

use flate2::read::DeflateDecoder;
use flate2::write::DeflateEncoder;
use flate2::Compression;

/// Appends `value` as an unsigned LEB128 varint (7 bits a byte, low first).
pub(crate) fn put_varint(out: &mut Vec<u8>, mut value: u64) {
    while value >= 0x80 {
        out.push((value as u8) | 0x80);
        value >>= 7;
    }
    out.push(value as u8);
}

/// Appends a signed integer zig-zag encoded (0, −1, 1, −2, … → 0, 1, 2, 3, …), as a varint.
pub(crate) fn put_signed(out: &mut Vec<u8>, value: i64) {
    put_varint(out, ((value << 1) ^ (value >> 63)) as u64);
}

/// Appends a byte string: its length as a varint, then the bytes.
pub(crate) fn put_bytes(out: &mut Vec<u8>, bytes: &[u8]) {
    put_varint(out, bytes.len() as u64);
    out.extend_from_slice(bytes);
}

/// Appends a string table: the number of strings, then each as [`put_bytes`].
pub(crate) fn put_strings<S: AsRef<str>>(out: &mut Vec<u8>, strings: &[S]) {
    put_varint(out, strings.len() as u64);
    for text in strings {
        put_bytes(out, text.as_ref().as_bytes());
    }
}

/// The string at `index` of a table read by [`Reader::strings`].
///
/// # Errors
/// An index past the table's end.
pub(crate) fn string_at<'a>(table: &[&'a str], index: u64) -> Result<&'a str, String> {
    usize::try_from(index)
        .ok()
        .and_then(|i| table.get(i).copied())
        .ok_or_else(|| format!("string {index} of {}", table.len()))
}

/// Appends an `f64`'s IEEE-754 bits, little-endian (exact).
pub(crate) fn put_f64(out: &mut Vec<u8>, value: f64) {
    out.extend_from_slice(&value.to_le_bytes());
}

/// Reads the fields [`put_varint`] and friends wrote; every read fails with a message on
/// truncated or malformed input, never panics.
pub(crate) struct Reader<'a> {
    bytes: &'a [u8],
}

impl<'a> Reader<'a> {
    pub(crate) fn new(bytes: &'a [u8]) -> Self {
        Self { bytes }
    }

    /// Whether everything has been read.
    pub(crate) fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }

    pub(crate) fn varint(&mut self) -> Result<u64, String> {
        let mut value = 0u64;
        for shift in (0..64).step_by(7) {
            let (&byte, rest) = self.bytes.split_first().ok_or("truncated varint")?;
            self.bytes = rest;
            value |= u64::from(byte & 0x7f) << shift;
            if byte & 0x80 == 0 {
                return Ok(value);
            }
        }
        Err("varint longer than 64 bits".into())
    }

    pub(crate) fn signed(&mut self) -> Result<i64, String> {
        let zigzag = self.varint()?;
        Ok(((zigzag >> 1) as i64) ^ -((zigzag & 1) as i64))
    }

    pub(crate) fn byte(&mut self) -> Result<u8, String> {
        let (&byte, rest) = self.bytes.split_first().ok_or("truncated byte")?;
        self.bytes = rest;
        Ok(byte)
    }

    pub(crate) fn bytes(&mut self) -> Result<&'a [u8], String> {
        let length = usize::try_from(self.varint()?).map_err(|_| "byte string too long")?;
        if length > self.bytes.len() {
            return Err(format!("byte string of {length} bytes, {} left", self.bytes.len()));
        }
        let (bytes, rest) = self.bytes.split_at(length);
        self.bytes = rest;
        Ok(bytes)
    }

    pub(crate) fn text(&mut self) -> Result<&'a str, String> {
        std::str::from_utf8(self.bytes()?).map_err(|e| format!("text not UTF-8: {e}"))
    }

    /// A string table written by [`put_strings`].
    pub(crate) fn strings(&mut self) -> Result<Vec<&'a str>, String> {
        let count = self.varint()?;
        // each string takes at least its length byte: a count beyond what is left is corrupt
        if count > self.bytes.len() as u64 {
            return Err(format!("{count} strings in {} bytes", self.bytes.len()));
        }
        (0..count).map(|_| self.text()).collect()
    }

    pub(crate) fn f64(&mut self) -> Result<f64, String> {
        if self.bytes.len() < 8 {
            return Err("truncated f64".into());
        }
        let (bits, rest) = self.bytes.split_at(8);
        self.bytes = rest;
        let mut array = [0u8; 8];
        array.copy_from_slice(bits);
        Ok(f64::from_le_bytes(array))
    }
}

/// `format` then the DEFLATE stream of `fields` (level 6, the zlib default).
pub(crate) fn deflate(format: u8, fields: &[u8]) -> Vec<u8> {
    let mut encoder = DeflateEncoder::new(vec![format], Compression::default());
    // writing to a Vec cannot fail
    let _ = encoder.write_all(fields);
    encoder.finish().unwrap_or_default()
}

/// Splits a payload into its format byte and inflated fields.
///
/// # Errors
/// An empty payload or a corrupt DEFLATE stream, as a message.
pub(crate) fn inflate(payload: &[u8]) -> Result<(u8, Vec<u8>), String> {
    let (&format, stream) = payload.split_first().ok_or("empty block")?;
    let mut fields = Vec::with_capacity(stream.len() * 4);
    DeflateDecoder::new(stream)
        .read_to_end(&mut fields)
        .map_err(|e| format!("corrupt block: {e}"))?;
    Ok((format, fields))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn varints_and_signed_integers_round_trip_at_their_extremes() {
        let unsigned = [0, 1, 127, 128, 300, u64::from(u32::MAX), u64::MAX];
        let signed = [0, -1, 1, -64, 64, i64::MIN, i64::MAX];
        let mut out = Vec::new();
        for value in unsigned {
            put_varint(&mut out, value);
        }
        for value in signed {
            put_signed(&mut out, value);
        }
        put_f64(&mut out, -0.1);
        put_bytes(&mut out, "zone Å".as_bytes());
        let mut reader = Reader::new(&out);
        for value in unsigned {
            assert_eq!(reader.varint().unwrap(), value);
        }
        for value in signed {
            assert_eq!(reader.signed().unwrap(), value);
        }
        assert_eq!(reader.f64().unwrap().to_bits(), (-0.1f64).to_bits());
        assert_eq!(reader.text().unwrap(), "zone Å");
        assert!(reader.is_empty());
        assert!(reader.byte().is_err(), "reading past the end is an error");
    }

    #[test]
    fn truncated_or_corrupt_input_is_an_error_not_a_panic() {
        assert!(Reader::new(&[0x80, 0x80]).varint().is_err());
        assert!(Reader::new(&[0xff; 11]).varint().is_err());
        assert!(Reader::new(&[5, b'a']).bytes().is_err());
        assert!(Reader::new(&[1, 2, 3]).f64().is_err());
        assert!(inflate(&[]).is_err());
        assert!(inflate(&[1, 0xff, 0xfe, 0x00]).is_err());
        let packed = deflate(7, b"the same words, the same words, the same words");
        assert!(packed.len() < 40, "repetition compresses: {} bytes", packed.len());
        assert_eq!(
            inflate(&packed).unwrap(),
            (7, b"the same words, the same words, the same words".to_vec())
        );
    }
}
