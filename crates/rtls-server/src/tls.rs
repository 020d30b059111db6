//! TLS for the listeners (HTTPS and WSS, MQTTS): the certificate and key from PEM files,
//! reloaded when the files change (a renewed certificate is served without a restart), or a
//! self-signed one generated for a demo; and the client side (PostgreSQL, an external MQTT
//! broker): `client_config`.
//!
//! rustls with the *ring* provider, TLS 1.2 and 1.3 (rustls's safe defaults).

use std::path::{Path, PathBuf};
use std::sync::{Arc, RwLock};
use std::time::{Duration, SystemTime};

use rustls::crypto::ring::default_provider;
use rustls::server::{ClientHello, ResolvesServerCert};
use rustls::sign::CertifiedKey;
use rustls::{ClientConfig, RootCertStore, ServerConfig};
use rustls_pki_types::pem::PemObject;
use rustls_pki_types::{CertificateDer, PrivateKeyDer};
use tokio::sync::watch;
use tokio_rustls::TlsAcceptor;

/// Why TLS could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum TlsError {
    /// A certificate or key file cannot be read or holds nothing usable.
    #[error("TLS {what} {path}: {reason}")]
    File {
        /// `certificate` or `key`.
        what: &'static str,
        /// The file.
        path: String,
        /// What is wrong.
        reason: String,
    },
    /// rustls refused the certificate and key (e.g. they do not match).
    #[error("TLS: {0}")]
    Rustls(String),
}

/// Where the certificate and key are, and how often their files are checked for a change.
#[derive(Debug, Clone, PartialEq)]
pub struct TlsFiles {
    /// The certificate chain, PEM (the server's certificate first).
    pub cert: PathBuf,
    /// The private key, PEM (PKCS#8, PKCS#1 or SEC1).
    pub key: PathBuf,
    /// How often the files' modification times are checked.
    pub reload_every: Duration,
}

/// A rustls client configuration (ring, TLS 1.2 and 1.3) verifying the server against the CA
/// certificates of `ca_file` (PEM), or the system's trust store when `None`, with an optional
/// client identity (certificate chain and key, PEM) for mutual TLS. `names` are the settings
/// the three files came from (e.g. `ca_file`, `sslrootcert`), for the errors.
///
/// # Errors
/// In words, naming the setting and the file: a file cannot be read or holds nothing usable, the system's trust store is empty, or rustls
/// refuses a certificate or the key.
pub(crate) fn client_config(
    ca_file: Option<&Path>,
    client_identity: Option<(&Path, &Path)>,
    [ca_name, cert_name, key_name]: [&str; 3],
) -> Result<ClientConfig, String> {
    let mut roots = RootCertStore::empty();
    match ca_file {
        Some(path) => {
            let shown = path.display();
            for certificate in CertificateDer::pem_file_iter(path).map_err(|e| format!("{ca_name} {shown}: {e}"))? {
                let certificate = certificate.map_err(|e| format!("{ca_name} {shown}: {e}"))?;
                roots.add(certificate).map_err(|e| format!("{ca_name} {shown}: {e}"))?;
            }
            if roots.is_empty() {
                return Err(format!("{ca_name} {shown}: no CERTIFICATE block in the file"));
            }
        }
        None => {
            let found = rustls_native_certs::load_native_certs();
            let (added, _ignored) = roots.add_parsable_certificates(found.certs);
            if added == 0 {
                return Err(format!(
                    "no CA certificate in the system's trust store ({} errors): name one with {ca_name}",
                    found.errors.len()
                ));
            }
        }
    }
    let builder = ClientConfig::builder_with_provider(Arc::new(default_provider()))
        .with_safe_default_protocol_versions()
        .map_err(|e| e.to_string())?
        .with_root_certificates(roots);
    match client_identity {
        None => Ok(builder.with_no_client_auth()),
        Some((cert_file, key_file)) => {
            let chain = CertificateDer::pem_file_iter(cert_file)
                .and_then(Iterator::collect::<Result<Vec<_>, _>>)
                .map_err(|e| format!("{cert_name} {}: {e}", cert_file.display()))?;
            if chain.is_empty() {
                return Err(format!(
                    "{cert_name} {}: no CERTIFICATE block in the file",
                    cert_file.display()
                ));
            }
            let key = PrivateKeyDer::from_pem_file(key_file)
                .map_err(|e| format!("{key_name} {}: {e}", key_file.display()))?;
            builder
                .with_client_auth_cert(chain, key)
                .map_err(|e| format!("client certificate: {e}"))
        }
    }
}

/// Reads a certificate chain and its key into what rustls serves.
///
/// # Errors
/// [`TlsError::File`] naming the file that cannot be read or parsed; [`TlsError::Rustls`] when
/// the key is not usable or does not match the certificate.
pub fn load(cert: &Path, key: &Path) -> Result<CertifiedKey, TlsError> {
    let file_error = |what: &'static str, path: &Path, reason: String| TlsError::File {
        what,
        path: path.display().to_string(),
        reason,
    };
    let chain: Vec<CertificateDer<'static>> = CertificateDer::pem_file_iter(cert)
        .map_err(|e| file_error("certificate", cert, e.to_string()))?
        .collect::<Result<_, _>>()
        .map_err(|e| file_error("certificate", cert, e.to_string()))?;
    if chain.is_empty() {
        return Err(file_error(
            "certificate",
            cert,
            "no CERTIFICATE block in the file".into(),
        ));
    }
    let private_key = PrivateKeyDer::from_pem_file(key).map_err(|e| file_error("key", key, e.to_string()))?;
    let signing_key = default_provider()
        .key_provider
        .load_private_key(private_key)
        .map_err(|e| TlsError::Rustls(format!("key {}: {e}", key.display())))?;
    let certified = CertifiedKey::new(chain, signing_key);
    certified
        .keys_match()
        .map_err(|e| TlsError::Rustls(format!("{} and {}: {e}", cert.display(), key.display())))?;
    Ok(certified)
}

/// Serves the current certificate to every handshake; [`CertificateStore::reload`] swaps it.
#[derive(Debug)]
pub struct CertificateStore {
    current: RwLock<Arc<CertifiedKey>>,
}

impl CertificateStore {
    /// A store serving `certified`.
    #[must_use]
    pub fn new(certified: CertifiedKey) -> Arc<Self> {
        Arc::new(Self {
            current: RwLock::new(Arc::new(certified)),
        })
    }

    /// Serves `certified` from the next handshake on.
    pub fn replace(&self, certified: CertifiedKey) {
        if let Ok(mut current) = self.current.write() {
            *current = Arc::new(certified);
        }
    }

    /// Loads the files again and serves them from the next handshake on.
    ///
    /// # Errors
    /// As [`load`]; the certificate served until now stays.
    pub fn reload(&self, files: &TlsFiles) -> Result<(), TlsError> {
        self.replace(load(&files.cert, &files.key)?);
        Ok(())
    }

    /// A rustls acceptor offering `alpn` (e.g. `http/1.1`) with this store's certificate.
    ///
    /// # Errors
    /// [`TlsError::Rustls`] when rustls cannot build the configuration.
    pub fn acceptor(self: &Arc<Self>, alpn: &[&[u8]]) -> Result<TlsAcceptor, TlsError> {
        let mut config = ServerConfig::builder_with_provider(Arc::new(default_provider()))
            .with_safe_default_protocol_versions()
            .map_err(|e| TlsError::Rustls(e.to_string()))?
            .with_no_client_auth()
            .with_cert_resolver(Arc::clone(self) as Arc<dyn ResolvesServerCert>);
        config.alpn_protocols = alpn.iter().map(|p| p.to_vec()).collect();
        Ok(TlsAcceptor::from(Arc::new(config)))
    }
}

impl ResolvesServerCert for CertificateStore {
    fn resolve(&self, _client_hello: ClientHello<'_>) -> Option<Arc<CertifiedKey>> {
        self.current.read().ok().map(|current| Arc::clone(&current))
    }
}

/// The newer of the two files' modification times.
fn modified(files: &TlsFiles) -> Option<SystemTime> {
    let time = |path: &Path| std::fs::metadata(path).and_then(|m| m.modified()).ok();
    time(&files.cert).max(time(&files.key))
}

/// Checks the files every `files.reload_every` and reloads `store` when they changed, until
/// `stop` turns true. A failed reload is logged and the served certificate stays.
pub async fn watch_files(store: Arc<CertificateStore>, files: TlsFiles, mut stop: watch::Receiver<bool>) {
    let mut seen = modified(&files);
    loop {
        tokio::select! {
            () = tokio::time::sleep(files.reload_every) => {}
            _ = stop.changed() => return,
        }
        let now = modified(&files);
        if now == seen {
            continue;
        }
        seen = now;
        match store.reload(&files) {
            Ok(()) => tracing::info!(cert = %files.cert.display(), "tls: certificate reloaded"),
            Err(e) => tracing::error!(error = %e, "tls: reloading the certificate failed; the previous one is served"),
        }
    }
}

/// Writes a self-signed certificate for `names` (DNS names or IP addresses) and its key to
/// `cert` and `key` (PEM; the key readable by its owner only), unless both files exist.
/// Clients trust it by its file (`curl --cacert`, `mosquitto_pub --cafile`).
///
/// # Errors
/// [`TlsError::File`] when a file cannot be written; [`TlsError::Rustls`] when generation fails.
pub fn ensure_self_signed(cert: &Path, key: &Path, names: &[String]) -> Result<bool, TlsError> {
    if cert.exists() && key.exists() {
        return Ok(false);
    }
    let generated = rcgen::generate_simple_self_signed(names.to_vec())
        .map_err(|e| TlsError::Rustls(format!("self-signed: {e}")))?;
    let write = |what: &'static str, path: &Path, text: String| {
        write_private(path, text.as_bytes()).map_err(|e| TlsError::File {
            what,
            path: path.display().to_string(),
            reason: e.to_string(),
        })
    };
    write("certificate", cert, generated.cert.pem())?;
    write("key", key, generated.key_pair.serialize_pem())?;
    Ok(true)
}

/// Writes `bytes` to a new file readable by its owner only (on Unix).
fn write_private(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    use std::io::Write;
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create(true).truncate(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
    options.open(path)?.write_all(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("rtls-tls-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn a_self_signed_certificate_is_written_once_and_loads() {
        let dir = temp("self-signed");
        let (cert, key) = (dir.join("c.pem"), dir.join("k.pem"));
        let names = vec!["localhost".to_string(), "127.0.0.1".to_string()];
        assert!(ensure_self_signed(&cert, &key, &names).unwrap(), "written");
        let first = std::fs::read(&cert).unwrap();
        assert!(!ensure_self_signed(&cert, &key, &names).unwrap(), "kept");
        assert_eq!(std::fs::read(&cert).unwrap(), first);
        let certified = load(&cert, &key).expect("loads");
        assert_eq!(certified.cert.len(), 1);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&key).unwrap().permissions().mode() & 0o777;
            assert_eq!(mode, 0o600, "the key is private");
        }
    }

    #[test]
    fn bad_files_are_named_and_a_mismatched_key_is_refused() {
        let dir = temp("bad");
        let missing = load(&dir.join("nope.pem"), &dir.join("nope.key"))
            .unwrap_err()
            .to_string();
        assert!(
            missing.contains("certificate") && missing.contains("nope.pem"),
            "{missing}"
        );
        std::fs::write(dir.join("empty.pem"), "not a certificate\n").unwrap();
        let empty = load(&dir.join("empty.pem"), &dir.join("nope.key"))
            .unwrap_err()
            .to_string();
        assert!(empty.contains("no CERTIFICATE block"), "{empty}");
        let names = vec!["localhost".to_string()];
        let (a_cert, a_key) = (dir.join("a.pem"), dir.join("a.key"));
        let (b_cert, b_key) = (dir.join("b.pem"), dir.join("b.key"));
        ensure_self_signed(&a_cert, &a_key, &names).unwrap();
        ensure_self_signed(&b_cert, &b_key, &names).unwrap();
        let mismatch = load(&a_cert, &b_key).unwrap_err().to_string();
        assert!(mismatch.contains("a.pem"), "{mismatch}");
    }
}
