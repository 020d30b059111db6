//! TLS to the external broker, asked for in the bridge's URL:
//! `mqtts://broker:8883?ca_file=/etc/rtls/broker-ca.pem` (port 8883 unless the URL names one).
//!
//! - `mqtts://` or `ssl://`: TLS (rustls, ring), the broker's certificate verified — chain and
//!   host name, always — against the CA certificates of `ca_file` (PEM), or against the
//!   operating system's trust store when the URL names none;
//! - `client_cert_file` and `client_key_file` (PEM, both or neither): a client certificate for
//!   brokers that authenticate clients by certificate (mutual TLS);
//! - `mqtt://` or `tcp://` with any of these options is refused: a CA file on a plain URL would
//!   suggest an encryption that does not happen.
//!
//! rumqttc would build its own TLS configuration for an `mqtts://` URL from the process-wide
//! crypto provider and panic when none is installed, so the options are split off here and the
//! URL handed to rumqttc says `mqtt://`; the bridge then sets the transport from
//! [`client_config`].

use std::path::{Path, PathBuf};

use rustls::ClientConfig;

/// The broker's TLS port when an `mqtts://` URL names none.
pub(super) const DEFAULT_TLS_PORT: u16 = 8883;

/// What the URL asks for.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) enum BrokerTls {
    /// Plain TCP.
    Off,
    /// TLS.
    On {
        /// CA certificates (PEM) to verify the broker against; the system's trust store when
        /// `None`.
        ca_file: Option<PathBuf>,
        /// The client's certificate chain and private key (PEM), for mutual TLS.
        client_identity: Option<(PathBuf, PathBuf)>,
    },
}

/// Splits the TLS options off `url`: a URL rumqttc parses (`mqtt://`, the port made explicit)
/// and the TLS asked for.
///
/// # Errors
/// What is wrong with the scheme or the TLS options, in words.
pub(super) fn split(url: &str) -> Result<(String, BrokerTls), String> {
    let mut parsed = url::Url::parse(url).map_err(|error| error.to_string())?;
    let tls_scheme = matches!(parsed.scheme(), "mqtts" | "ssl");
    let mut ca_file = None;
    let mut client_cert = None;
    let mut client_key = None;
    let mut kept = Vec::new();
    for (key, value) in parsed.query_pairs() {
        match key.as_ref() {
            "ca_file" => ca_file = Some(PathBuf::from(value.as_ref())),
            "client_cert_file" => client_cert = Some(PathBuf::from(value.as_ref())),
            "client_key_file" => client_key = Some(PathBuf::from(value.as_ref())),
            _ => kept.push((key.into_owned(), value.into_owned())),
        }
    }
    let client_identity = match (client_cert, client_key) {
        (Some(cert), Some(key)) => Some((cert, key)),
        (None, None) => None,
        _ => return Err("client_cert_file and client_key_file go together: give both or neither".into()),
    };
    if !tls_scheme {
        if ca_file.is_some() || client_identity.is_some() {
            return Err(format!(
                "ca_file, client_cert_file and client_key_file need TLS: write mqtts:// instead of {}://",
                parsed.scheme()
            ));
        }
        return Ok((url.to_owned(), BrokerTls::Off));
    }
    let port = parsed.port().unwrap_or(DEFAULT_TLS_PORT);
    parsed.set_query(None);
    if !kept.is_empty() {
        parsed.query_pairs_mut().extend_pairs(kept);
    }
    // `mqtts` is not a special scheme of the URL standard, so the scheme and port can be set.
    let rest = parsed
        .as_str()
        .split_once("://")
        .map_or("", |(_, rest)| rest)
        .to_owned();
    let mut plain = url::Url::parse(&format!("mqtt://{rest}")).map_err(|error| error.to_string())?;
    plain
        .set_port(Some(port))
        .map_err(|()| "the URL has no host".to_string())?;
    Ok((
        plain.into(),
        BrokerTls::On {
            ca_file,
            client_identity,
        },
    ))
}

/// A rustls client configuration for `ca_file` (or the system's trust store) and an optional
/// client identity: [`crate::tls::client_config`], its errors naming the URL's options.
///
/// # Errors
/// As [`crate::tls::client_config`].
pub(super) fn client_config(
    ca_file: Option<&Path>,
    client_identity: Option<(&Path, &Path)>,
) -> Result<ClientConfig, String> {
    crate::tls::client_config(
        ca_file,
        client_identity,
        ["ca_file", "client_cert_file", "client_key_file"],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tls_options_are_split_off_and_the_port_defaults_to_8883() {
        let (plain, tls) = split("mqtts://u:p@broker?ca_file=/etc/ca.pem&client_id=site-2").expect("valid");
        assert_eq!(plain, "mqtt://u:p@broker:8883?client_id=site-2");
        assert_eq!(
            tls,
            BrokerTls::On {
                ca_file: Some(PathBuf::from("/etc/ca.pem")),
                client_identity: None
            }
        );
        let (plain, tls) = split("ssl://broker:18831?client_cert_file=c.pem&client_key_file=k.pem").expect("valid");
        assert_eq!(plain, "mqtt://broker:18831");
        assert_eq!(
            tls,
            BrokerTls::On {
                ca_file: None,
                client_identity: Some((PathBuf::from("c.pem"), PathBuf::from("k.pem")))
            }
        );
        let (plain, tls) = split("mqtt://broker:1883?client_id=a").expect("valid");
        assert_eq!(
            (plain.as_str(), tls),
            ("mqtt://broker:1883?client_id=a", BrokerTls::Off)
        );
    }

    #[test]
    fn tls_options_without_tls_or_halves_of_an_identity_are_refused() {
        let error = split("mqtt://broker?ca_file=/etc/ca.pem").unwrap_err();
        assert!(error.contains("mqtts://"), "{error}");
        let error = split("mqtts://broker?client_cert_file=c.pem").unwrap_err();
        assert!(error.contains("go together"), "{error}");
    }

    #[test]
    fn a_ca_file_without_certificates_is_refused_with_its_name() {
        let dir = std::env::temp_dir().join(format!("rtls-bridge-tls-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let empty = dir.join("empty.pem");
        std::fs::write(&empty, "not a certificate\n").expect("write");
        let error = client_config(Some(&empty), None).unwrap_err();
        assert!(
            error.contains("empty.pem") && error.contains("no CERTIFICATE"),
            "{error}"
        );
        let missing = dir.join("missing.pem");
        let error = client_config(Some(&missing), None).unwrap_err();
        assert!(error.contains("missing.pem"), "{error}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
