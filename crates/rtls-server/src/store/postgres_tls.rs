//! TLS to PostgreSQL, asked for in the connection URL as libpq spells it:
//! `?sslmode=require&sslrootcert=/etc/rtls/pg-ca.crt`.
//!
//! - no `sslmode` (or `disable`): plain TCP, as before;
//! - `require`, `verify-ca`, `verify-full`: TLS, the server's certificate verified against the
//!   CA certificates in `sslrootcert` (PEM) — chain *and* host name, always (rustls does not
//!   offer libpq's unverified `require`); without `sslrootcert` the URL is refused;
//! - `prefer` and `allow` are refused: they fall back to plain text without a word.
//!
//! rust-postgres takes neither option in this form, so both are split off the URL before it
//! parses the rest.

use std::path::PathBuf;

use tokio_postgres_rustls::MakeRustlsConnect;

/// What the URL asks for.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) enum PgTls {
    /// Plain TCP.
    Off,
    /// TLS, the server verified against the CA certificates in this file.
    Verified(PathBuf),
}

/// Splits `sslmode` and `sslrootcert` off `url`: the URL without them, and the TLS asked for.
///
/// # Errors
/// What is wrong with the two options, in words.
pub(super) fn split(url: &str) -> Result<(String, PgTls), String> {
    let Some((base, query)) = url.split_once('?') else {
        return Ok((url.to_string(), PgTls::Off));
    };
    let mut mode = None;
    let mut root_cert = None;
    let mut kept = Vec::new();
    for pair in query.split('&').filter(|p| !p.is_empty()) {
        match pair.split_once('=') {
            Some(("sslmode", value)) => mode = Some(value.to_string()),
            Some(("sslrootcert", value)) => root_cert = Some(PathBuf::from(value)),
            _ => kept.push(pair),
        }
    }
    let rebuilt = if kept.is_empty() {
        base.to_string()
    } else {
        format!("{base}?{}", kept.join("&"))
    };
    let tls = match (mode.as_deref(), root_cert) {
        (None | Some("disable"), None) => PgTls::Off,
        (Some("disable"), Some(_)) => return Err("sslmode=disable with sslrootcert: choose one".into()),
        (Some("prefer" | "allow"), _) => {
            return Err(
                "sslmode=prefer and allow fall back to plain text: use sslmode=require (TLS, the \
                        server's certificate verified against sslrootcert) or disable"
                    .into(),
            )
        }
        (None | Some("require" | "verify-ca" | "verify-full"), Some(ca)) => PgTls::Verified(ca),
        (Some("require" | "verify-ca" | "verify-full"), None) => {
            return Err(
                "sslmode=require needs sslrootcert=PATH (a PEM file of the CA certificates that \
                        signed the server's certificate)"
                    .into(),
            )
        }
        (Some(other), _) => {
            return Err(format!(
                "sslmode={other} is not disable, require, verify-ca or verify-full"
            ))
        }
    };
    Ok((rebuilt, tls))
}

/// A connector verifying the server against the CA certificates in `ca_file`.
///
/// # Errors
/// The file cannot be read, holds no certificate, or one rustls refuses.
pub(super) fn connector(ca_file: &std::path::Path) -> Result<MakeRustlsConnect, String> {
    let config = crate::tls::client_config(Some(ca_file), None, ["sslrootcert", "sslcert", "sslkey"])?;
    Ok(MakeRustlsConnect::new(config))
}

#[cfg(test)]
mod tests {
    use super::super::PostgresStore;
    use super::*;

    /// `.ci/services/postgres.sh` offers TLS with a certificate for 127.0.0.1 from a CA of its
    /// own, and names the CA in `RTLS_TEST_POSTGRES_CA`.
    #[test]
    fn a_verified_connection_is_encrypted_and_a_foreign_ca_is_refused() {
        let (Ok(url), Ok(ca)) = (
            std::env::var("RTLS_TEST_POSTGRES_URL"),
            std::env::var("RTLS_TEST_POSTGRES_CA"),
        ) else {
            eprintln!("skipped: RTLS_TEST_POSTGRES_URL and RTLS_TEST_POSTGRES_CA not set");
            return;
        };
        let encrypted = |client: &mut ::postgres::Client| -> bool {
            client
                .query_one("SELECT ssl FROM pg_stat_ssl WHERE pid = pg_backend_pid()", &[])
                .expect("pg_stat_ssl")
                .get(0)
        };
        let mut tls =
            PostgresStore::client(&format!("{url}?sslmode=require&sslrootcert={ca}")).expect("TLS connection");
        assert!(encrypted(&mut tls), "the session is encrypted");
        let mut plain = PostgresStore::client(&url).expect("plain connection");
        assert!(!encrypted(&mut plain), "without sslmode, plain as before");
        // a CA that did not sign the server's certificate
        let dir = std::env::temp_dir().join(format!("rtls-pg-tls-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (foreign, foreign_key) = (dir.join("foreign.crt"), dir.join("foreign.key"));
        crate::tls::ensure_self_signed(&foreign, &foreign_key, &["127.0.0.1".to_string()]).unwrap();
        let refused = PostgresStore::client(&format!("{url}?sslmode=verify-full&sslrootcert={}", foreign.display()))
            .err()
            .expect("a foreign CA is refused")
            .to_string();
        assert!(
            refused.contains("certificate") || refused.contains("Issuer"),
            "{refused}"
        );
        assert!(!refused.contains(":rtls@"), "the password is redacted: {refused}");
    }

    #[test]
    fn the_two_options_are_split_off_and_judged() {
        let plain = "postgres://u:p@h/db";
        assert_eq!(split(plain).unwrap(), (plain.to_string(), PgTls::Off));
        assert_eq!(
            split("postgres://u:p@h/db?sslmode=require&sslrootcert=/ca.pem&application_name=rtls").unwrap(),
            (
                "postgres://u:p@h/db?application_name=rtls".to_string(),
                PgTls::Verified("/ca.pem".into())
            )
        );
        assert_eq!(
            split("postgres://h/db?sslmode=verify-full&sslrootcert=/ca.pem")
                .unwrap()
                .0,
            "postgres://h/db"
        );
        assert_eq!(split("postgres://h/db?sslmode=disable").unwrap().1, PgTls::Off);
        assert!(split("postgres://h/db?sslmode=require")
            .unwrap_err()
            .contains("sslrootcert"));
        assert!(split("postgres://h/db?sslmode=prefer")
            .unwrap_err()
            .contains("plain text"));
        assert!(split("postgres://h/db?sslmode=sometimes&sslrootcert=/c")
            .unwrap_err()
            .contains("sometimes"));
    }
}
