//! Zebra Dart UWB RTLS: the hub's ASCII output in the Dart format (TCP port 5117), one packet
//! per line, read by [`ZebraAdapter`] (`[adapters.zebra]`).
//!
//! The format, its mapping to fixes and the accuracy: [`ZebraAdapter`].
//!
//! # References
//! - Zebra Enterprise Solutions, "Dart RTLS User Guide", document D2119 Rev F (2016),
//!   chapter 11 "System output", pages 83–88 (packet types, fields, units, DQI, GDOP,
//!   non-locate and locate details), "Configuring output control", pages 43–45, GDOP
//!   thresholds, page 71, and appendix A "Information Data (I-packets)", page 107. Public copy:
//!   <http://38.142.81.21:8001/manual/zebra/rtls/user-guide-german-english/page-83.html> (and
//!   the following pages).
//! - The example lines of the tests: the guide's "example of system output from a Dart RTLS
//!   Hub", page 85 (R, T, O, N and P packets with DQI, GDOP and details; the PDF wraps long
//!   lines, the hub sends each packet on one line), the P packets of page 86 and the I packet
//!   of page 107.

use serde::Deserialize;

use super::{fix, AdapterError, Parsed, Refusal};

/// Metres per international foot (exact).
const METRES_PER_FOOT: f64 = 0.3048;

/// `[adapters.zebra]`: how a Zebra Dart hub's output is read, and where the hub is.
///
/// A line is `<Data Header>,<tag>,<X>,<Y>,<Z>,<battery>,<timestamp>,<unit>[,<details>…]<LF>`;
/// a payload (an HTTP body, a datagram, a TCP read) holds one line or several.
///
/// | Dart field | record field |
/// | --- | --- |
/// | `<Data Header>` `R` (3-D locate) | a 3-D fix `[X, Y, Z]` |
/// | `<Data Header>` `T` (2-D locate; Z is the receivers' mean height) | a 2-D fix `[X, Y]` |
/// | `<Data Header>` `O` (1-D estimate: a point on the line between two receivers) | a 2-D fix `[X, Y]` weighed by `o_packet_accuracy_m` |
/// | `<tag>` (e.g. `0021F7B1`) | `tag`, as written |
/// | `<X>`, `<Y>`, `<Z>` in the hub's unit (`unit`: `m` or `ft`) | `position_m` |
/// | `<timestamp>` (Unix s, decimals: the hub's time of processing) | `t` |
/// | `G<GDOP>` among the details (`G*`: none) | `covariance_m2` = `(GDOP · range_sigma_m)² I`; without one `default_accuracy_m² I` |
/// | `P` (presence: X, Y, Z are the *receiver's*), `N` (non-locate), `D` (diagnostic), `I` (information) | refused, reason `no_position` |
///
/// # Accuracy
/// The hub states no accuracy in metres. Its GDOP (dimensionless, "calculated based on the
/// output tag location and configured location of involved receivers") scales the error of
/// the receivers' time-of-arrival ranges into the position's, so σ = GDOP × `range_sigma_m`
/// for each coordinate. The guide defines GDOP no further (2-D or 3-D, with or without a time
/// term), so the whole GDOP is taken for each coordinate: conservative by at most √3. The
/// default `range_sigma_m` (0.3 m) is a UWB time-of-arrival range error typical of deployed
/// systems, not a Zebra figure (the guide gives none): set it from a site survey. With the
/// guide's good-geometry GDOP of 1–2 (page 71) that is σ 0.3–0.6 m; its `G10000.00` lines are
/// weighed as the near-useless fixes they are (σ 3 km). A line without GDOP (the output option
/// off, or `G*`) gets `server.default_accuracy_m`, as the other adapters' messages without an
/// accuracy do. The DQI (a unitless residual of the hub's minimisation) is not used.
///
/// An O packet is a guess along the line between the only two receivers that heard the tag:
/// the tag may be anywhere across that line within both receivers' reach, tens of metres
/// from it, so its fix is weighed by `o_packet_accuracy_m` (default 10 m, a 95 % radius of
/// about 25 m), whatever the details say — wide enough that the tracker follows it only where
/// better fixes are missing.
///
/// # Malformed lines
/// A line that does not parse is an [`AdapterError`] naming the line and the field
/// (`line 2 <X>: expected a number (ft), got "abc"`). It costs that line only: in a payload of
/// several lines it becomes a [`Refusal`] with reason `format` and the error as its detail,
/// and the other lines are used. A payload whose every line is malformed is the error
/// itself (nothing of it is usable).
///
///
/// # Examples
/// ```
/// use rtls_server::adapters::ZebraAdapter;
/// let adapter: ZebraAdapter = toml::from_str(r#"unit = "ft""#).unwrap();
/// // from the Dart RTLS User Guide's example output (page 85)
/// let line = "T,00201C40,25.85,15.67,2.59,12,1433877589.612,4,0.74,G0.42,S42-S82-S43-S84-S81,H42-H82-H43-H84-H41P2P4-H81-HFF";
/// let parsed = adapter.parse(line.as_bytes(), 1.0).unwrap();
/// assert_eq!(parsed.records[0].tag, "00201C40");
/// assert_eq!(parsed.records[0].time_s, 1_433_877_589.612);
/// ```
///
/// # References
/// Zebra, "Dart RTLS User Guide", document D2119 Rev F, chapter 11 "System output", pages
/// 83–88; the sources of the tests' example lines are in `src/adapters/zebra.rs`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ZebraAdapter {
    /// The unit of the hub's coordinates (its configuration: feet or metres).
    pub unit: ZebraUnit,
    /// The σ of one receiver's range (m, > 0): a fix's σ is its GDOP times this.
    pub range_sigma_m: f64,
    /// The σ of an O packet's 1-D estimate (m, > 0).
    pub o_packet_accuracy_m: f64,
    /// The hub's Dart output, `HOST:PORT` (port 5117): `rtls serve` connects to it and reads
    /// its lines, reconnecting when the connection drops ([`crate::zebra_hub`]); none: the
    /// lines come over HTTP, MQTT or UDP only.
    pub hub: Option<String>,
    /// A hub connection that brings no byte for this long (s, > 0) is closed and opened again:
    /// a connection a network fault left half open shows nothing else.
    pub idle_timeout_s: f64,
}

impl Default for ZebraAdapter {
    fn default() -> Self {
        Self {
            unit: ZebraUnit::M,
            range_sigma_m: 0.3,
            o_packet_accuracy_m: 10.0,
            hub: None,
            idle_timeout_s: 300.0,
        }
    }
}

/// The unit of a Dart hub's coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ZebraUnit {
    /// Metres.
    #[default]
    M,
    /// International feet (0.3048 m).
    Ft,
}

impl ZebraUnit {
    fn metres(self) -> f64 {
        match self {
            ZebraUnit::M => 1.0,
            ZebraUnit::Ft => METRES_PER_FOOT,
        }
    }

    fn name(self) -> &'static str {
        match self {
            ZebraUnit::M => "m",
            ZebraUnit::Ft => "ft",
        }
    }
}

/// What one line is: a fix, or a packet without the tag's position.
enum Packet {
    Fix(rtls_engine::record::Record),
    Refused(Refusal),
}

impl ZebraAdapter {
    /// Checks the settings' ranges and that `hub` is `HOST:PORT`.
    ///
    /// # Errors
    /// The setting that is wrong, and why (`range_sigma_m: …`).
    pub fn validate(&self) -> Result<(), String> {
        for (name, value) in [
            ("range_sigma_m", self.range_sigma_m),
            ("o_packet_accuracy_m", self.o_packet_accuracy_m),
            ("idle_timeout_s", self.idle_timeout_s),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(format!("{name}: must be a finite number > 0, got {value}"));
            }
        }
        if let Some(hub) = &self.hub {
            let port = hub.rsplit_once(':').filter(|(host, _)| !host.is_empty());
            if port.is_none_or(|(_, port)| port.parse::<u16>().is_err()) {
                return Err(format!(
                    "hub: `{hub}` is not HOST:PORT, e.g. \"10.0.0.5:5117\" (the hub's Dart output port)"
                ));
            }
        }
        Ok(())
    }

    /// Parses one payload of the hub's Dart output: each line a packet (see
    /// [`ZebraAdapter`] for the mapping, the accuracy and refusals). `default_accuracy_m` (σ, m)
    /// weighs fixes without a GDOP.
    ///
    /// # Errors
    /// [`AdapterError::Field`] naming the line and field when the payload is not text, or when
    /// every one of its lines is malformed (the first line's error).
    pub fn parse(&self, payload: &[u8], default_accuracy_m: f64) -> Result<Parsed, AdapterError> {
        let text = std::str::from_utf8(payload).map_err(|e| {
            let line = 1 + payload[..e.valid_up_to()].iter().filter(|&&b| b == b'\n').count();
            AdapterError::field(
                format!("line {line}"),
                "not ASCII text: send the hub's Dart output (TCP port 5117) unchanged",
            )
        })?;
        let mut parsed = Parsed::default();
        let mut first_error = None;
        let mut usable = false;
        for (index, line) in text.split('\n').enumerate() {
            let line = line.trim();
            if line.is_empty() {
                continue;
            }
            let at = format!("line {}", index + 1);
            match self.packet(line, &at, default_accuracy_m) {
                Ok(Packet::Fix(record)) => {
                    usable = true;
                    parsed.records.push(record);
                }
                Ok(Packet::Refused(refusal)) => {
                    usable = true;
                    parsed.refusals.push(refusal);
                }
                Err(error) => {
                    parsed.refusals.push(Refusal {
                        tag: line
                            .split(',')
                            .nth(1)
                            .map(str::trim)
                            .filter(|t| !t.is_empty())
                            .map(str::to_string),
                        at,
                        reason: "format",
                        detail: error.to_string(),
                    });
                    first_error.get_or_insert(error);
                }
            }
        }
        match first_error {
            Some(error) if !usable => Err(error),
            _ => Ok(parsed),
        }
    }

    /// One line (trimmed, not empty), `at` naming it (`line 3`).
    fn packet(&self, line: &str, at: &str, default_accuracy_m: f64) -> Result<Packet, AdapterError> {
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let field = |name: &str| format!("{at} <{name}>");
        let header = fields[0];
        if !matches!(header, "R" | "T" | "O" | "P" | "N" | "D" | "I") {
            return Err(AdapterError::field(
                field("Data Header"),
                format!("expected R, T, O, P, N, D or I, got {header:?}"),
            ));
        }
        let tag = fields
            .get(1)
            .filter(|t| !t.is_empty())
            .ok_or_else(|| AdapterError::field(field("tag"), "required field is missing"))?
            .to_string();
        let refused = |tag: Option<String>, detail: String| {
            Ok(Packet::Refused(Refusal {
                at: at.to_string(),
                tag,
                reason: "no_position",
                detail,
            }))
        };
        let dimensions = match header {
            "R" => 3,
            "T" | "O" => 2,
            "P" => {
                let receiver = fields.get(7).copied().unwrap_or("?");
                return refused(
                    Some(tag),
                    format!("a presence (P) packet: X, Y, Z are receiver {receiver}'s coordinates, not the tag's"),
                );
            }
            "N" => {
                let reasons = fields.get(8).copied().unwrap_or("not given");
                return refused(
                    Some(tag),
                    format!("a non-locate (N) packet: no location was computed (non-locate details {reasons})"),
                );
            }
            "D" => {
                return refused(
                    None,
                    format!(
                        "a diagnostic (D) packet about {tag}: hub, receiver or reference-tag status, not a location"
                    ),
                )
            }
            // "I", the last of the headers checked above
            _ => {
                return refused(
                    Some(tag),
                    "an information (I) packet: tag or receiver status, not a location".to_string(),
                )
            }
        };
        let unit = self.unit.name();
        let required = |index: usize, name: &str| {
            fields
                .get(index)
                .copied()
                .filter(|v| !v.is_empty())
                .ok_or_else(|| AdapterError::field(field(name), "required field is missing"))
        };
        let number = |index: usize, name: &str, what: &str| {
            let text = required(index, name)?;
            text.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| AdapterError::field(field(name), format!("expected {what}, got {text:?}")))
        };
        let scale = self.unit.metres();
        let coordinate = |index: usize, name: &str| number(index, name, &format!("a number ({unit})"));
        let mut position_m = vec![coordinate(2, "X")? * scale, coordinate(3, "Y")? * scale];
        if dimensions == 3 {
            position_m.push(coordinate(4, "Z")? * scale);
        }
        let time_s = number(6, "timestamp", "Unix seconds, e.g. 1433877485.930")?;
        if time_s < 0.0 {
            return Err(AdapterError::field(
                field("timestamp"),
                format!("expected Unix seconds ≥ 0, got {time_s}"),
            ));
        }
        // the virtual group: present in every locate, not used
        required(7, "unit")?;
        let accuracy_m = if header == "O" {
            self.o_packet_accuracy_m
        } else {
            match gdop(&fields[8..], &field("GDOP"))? {
                // σ = GDOP · σ_range
                Some(gdop) => gdop * self.range_sigma_m,
                None => default_accuracy_m,
            }
        };
        Ok(Packet::Fix(fix(time_s, tag, position_m, accuracy_m)))
    }
}

/// The GDOP among a locate's details (`G0.73`; `G*`, or no `G…` field: none).
fn gdop(details: &[&str], field: &str) -> Result<Option<f64>, AdapterError> {
    let Some(text) = details.iter().find_map(|d| d.strip_prefix('G')) else {
        return Ok(None);
    };
    if text == "*" {
        return Ok(None);
    }
    text.parse::<f64>()
        .ok()
        .filter(|g| g.is_finite() && *g > 0.0)
        .map(Some)
        .ok_or_else(|| AdapterError::field(field, format!("expected G and a number > 0, or G*, got \"G{text}\"")))
}

#[cfg(test)]
mod tests {

    use super::super::fix_of;
    use super::{ZebraAdapter, ZebraUnit};

    /// The guide's example output (page 85), each packet on one line as the hub sends it.
    const EXAMPLE: &str = include_str!("zebra_dart_example.txt");

    fn feet() -> ZebraAdapter {
        ZebraAdapter {
            unit: ZebraUnit::Ft,
            ..ZebraAdapter::default()
        }
    }

    #[test]
    fn the_guides_example_gives_its_seven_locates_and_refuses_the_rest() {
        let parsed = feet().parse(EXAMPLE.as_bytes(), 1.0).unwrap();
        let tags: Vec<&str> = parsed.records.iter().map(|r| r.tag.as_str()).collect();
        assert_eq!(
            tags,
            ["0021F7B1", "00210E2C", "00201BCD", "00200012", "00201C40", "00210F44", "0021117B"]
        );
        // 11 N packets and a P packet
        assert_eq!(parsed.refusals.len(), 12);
        assert!(parsed.refusals.iter().all(|r| r.reason == "no_position"));
        assert_eq!(parsed.refusals[0].at, "line 2");
        assert_eq!(parsed.refusals[0].tag.as_deref(), Some("00210EA1"));
        assert!(parsed.refusals[0].detail.contains("M1M2M4"), "{:?}", parsed.refusals[0]);
        let presence = parsed.refusals.iter().find(|r| r.at == "line 17").unwrap();
        assert_eq!(presence.tag.as_deref(), Some("00210F51"));
        assert!(presence.detail.contains("receiver 05"), "{presence:?}");
    }

    #[test]
    fn r_is_3d_t_and_o_are_2d_in_metres_from_feet() {
        let parsed = feet().parse(EXAMPLE.as_bytes(), 1.0).unwrap();
        // R,00210E2C,24.45,15.25,2.59,…: 3-D
        let (position, _) = fix_of(&parsed.records[1]);
        let expected = [24.45 * 0.3048, 15.25 * 0.3048, 2.59 * 0.3048];
        assert_eq!(position.len(), 3);
        for (got, want) in position.iter().zip(expected) {
            assert!((got - want).abs() < 1e-12, "{position:?}");
        }
        assert_eq!(parsed.records[1].time_s, 1_433_877_485.942);
        // T,0021F7B1,29.53,18.38,1.52,…: 2-D, the receivers' mean height not used
        let (position, covariance) = fix_of(&parsed.records[0]);
        assert_eq!(position.len(), 2);
        assert!((position[0] - 29.53 * 0.3048).abs() < 1e-12);
        assert_eq!(covariance.len(), 4);
        // O,00200012,31.99,5.04,…: 2-D too
        assert_eq!(fix_of(&parsed.records[3]).0.len(), 2);
        // in metres the coordinates are taken as they are
        let metres = ZebraAdapter::default().parse(EXAMPLE.as_bytes(), 1.0).unwrap();
        assert_eq!(fix_of(&metres.records[1]).0, [24.45, 15.25, 2.59]);
    }

    #[test]
    fn gdop_scales_the_range_sigma_and_o_packets_get_their_own() {
        let adapter = ZebraAdapter {
            range_sigma_m: 0.25,
            o_packet_accuracy_m: 8.0,
            ..ZebraAdapter::default()
        };
        let parsed = adapter.parse(EXAMPLE.as_bytes(), 1.5).unwrap();
        let variance = |k: usize| fix_of(&parsed.records[k]).1[0];
        // T … G0.73: σ = 0.73 · 0.25 m
        assert!((variance(0) - (0.73_f64 * 0.25).powi(2)).abs() < 1e-12);
        // R … G10000.00: a near-useless fix, weighed so (σ = 2.5 km)
        assert!((variance(1) - 2500.0_f64.powi(2)).abs() < 1e-6);
        // O … G*: o_packet_accuracy_m
        assert_eq!(variance(3), 64.0);
        // T … 0.74,G0.42 (a DQI, then the GDOP)
        assert!((variance(4) - (0.42_f64 * 0.25).powi(2)).abs() < 1e-12);
        // without GDOP (the option off): the server's default accuracy
        let plain = adapter
            .parse(b"T,00200007,46.2,32.2,0.0,13,1282704616.251,3,S37-S38-S43", 1.5)
            .unwrap();
        assert_eq!(fix_of(&plain.records[0]).1, [2.25, 0.0, 0.0, 2.25]);
    }

    #[test]
    fn presence_diagnostic_and_information_packets_are_refused() {
        let payload = concat!(
            // page 86: P packets with non-locate details (min-units not met)
            "P,0000099C,6.3,43.4,8.5,13,1162219029.404,A1,M1\r\n",
            // page 107: a tag information packet
            "I,00200E8F,1,2.00,12,0,1435161191.102,3,‘DartWand changed tag blink rate‘\n",
            "D,00000004,0.0,0.0,0.0,0,1435161191.102,12,'receiver 04 not responding'\n",
        );
        let parsed = ZebraAdapter::default().parse(payload.as_bytes(), 1.0).unwrap();
        assert!(parsed.records.is_empty());
        let reasons: Vec<_> = parsed.refusals.iter().map(|r| (r.at.as_str(), r.reason)).collect();
        assert_eq!(
            reasons,
            [
                ("line 1", "no_position"),
                ("line 2", "no_position"),
                ("line 3", "no_position")
            ]
        );
        assert!(parsed.refusals[2].tag.is_none(), "a D packet names no tag");
    }

    #[test]
    fn a_malformed_line_names_its_field_and_costs_only_itself() {
        let adapter = feet();
        let error = |line: &str| adapter.parse(line.as_bytes(), 1.0).unwrap_err().to_string();
        assert_eq!(
            error("T,0021F7B1,29.5x,18.38,1.52,12,1433877485.930,4"),
            r#"line 1 <X>: expected a number (ft), got "29.5x""#
        );
        assert_eq!(
            error("R,00210E2C,24.45,15.25,,5,1433877485.942,4"),
            "line 1 <Z>: required field is missing"
        );
        assert_eq!(
            error("T,0021F7B1,29.53,18.38,1.52,12,yesterday,4"),
            r#"line 1 <timestamp>: expected Unix seconds, e.g. 1433877485.930, got "yesterday""#
        );
        assert_eq!(
            error("T,0021F7B1,29.53,18.38,1.52,12,1433877485.930"),
            "line 1 <unit>: required field is missing"
        );
        assert_eq!(
            error("T,0021F7B1,29.53,18.38,1.52,12,1433877485.930,4,*,Gx"),
            r#"line 1 <GDOP>: expected G and a number > 0, or G*, got "Gx""#
        );
        assert_eq!(
            error("Q,0021F7B1"),
            r#"line 1 <Data Header>: expected R, T, O, P, N, D or I, got "Q""#
        );
        assert_eq!(error("T,,1,2"), "line 1 <tag>: required field is missing");
        assert!(error("{\"tagId\": 1}").starts_with("line 1 <Data Header>"));
        assert!(adapter
            .parse(b"\xff\xfe", 1.0)
            .unwrap_err()
            .to_string()
            .contains("not ASCII text"));

        // among good lines, a bad one is listed and the rest is used
        let mut lines: Vec<&str> = EXAMPLE.lines().collect();
        lines[2] = "N,00200015,0.00";
        lines[3] = "R,00210E2C,24.45,15.25,2.59,5,1433877485.9.42,4,*,G10000.00";
        let parsed = adapter.parse(lines.join("\n").as_bytes(), 1.0).unwrap();
        assert_eq!(
            parsed.records.len(),
            6,
            "the R line is lost, the six other locates are not"
        );
        let bad: Vec<_> = parsed.refusals.iter().filter(|r| r.reason == "format").collect();
        assert_eq!(bad.len(), 1, "a short N packet is still an N packet: {bad:?}");
        assert_eq!(bad[0].at, "line 4");
        assert_eq!(bad[0].tag.as_deref(), Some("00210E2C"));
        assert!(bad[0].detail.starts_with("line 4 <timestamp>"), "{:?}", bad[0]);
    }

    #[test]
    fn settings_are_checked() {
        assert_eq!(ZebraAdapter::default().validate(), Ok(()));
        let hub = |hub: &str| {
            ZebraAdapter {
                hub: Some(hub.to_string()),
                ..ZebraAdapter::default()
            }
            .validate()
        };
        assert_eq!(hub("10.0.0.5:5117"), Ok(()));
        assert_eq!(hub("dart-hub.site.local:5117"), Ok(()));
        assert!(hub("10.0.0.5").unwrap_err().starts_with("hub:"));
        assert!(hub(":5117").unwrap_err().starts_with("hub:"));
        let sigma = ZebraAdapter {
            range_sigma_m: 0.0,
            ..ZebraAdapter::default()
        };
        assert!(sigma.validate().unwrap_err().starts_with("range_sigma_m:"));
        assert!(toml::from_str::<ZebraAdapter>("unit = \"yd\"").is_err());
        assert!(toml::from_str::<ZebraAdapter>("units = \"ft\"").is_err());
    }
}
