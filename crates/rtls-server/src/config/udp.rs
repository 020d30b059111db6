//! `[udp]`: the UDP ingest listeners ([`crate::udp`]), their keys and checks.

use std::net::SocketAddr;

use serde::Deserialize;

use super::ConfigError;
use crate::adapters::Vendor;

/// `[udp]`: where gateways push datagrams (best-effort: no acknowledgement). Off unless an
/// address is given.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct UdpSection {
    /// A listener whose datagrams are each one payload of our measurement JSON lines (the body
    /// of `POST /api/v1/measurements`).
    pub listen: Option<SocketAddr>,
    /// `[udp.adapters]`: a listener per vendor whose datagrams are each one message of that
    /// vendor's feed, read by its adapter as `POST /api/v1/adapters/{vendor}` does.
    pub adapters: UdpAdapters,
}

/// `[udp.adapters]`: one listen address per vendor adapter ([`Vendor`]).
#[derive(Debug, Clone, PartialEq, Eq, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct UdpAdapters {
    /// Pozyx's `tags` stream messages.
    pub pozyx: Option<SocketAddr>,
    /// Quuppa QPE `DefaultLocation` tag data (a QPE "UDP output target").
    pub quuppa: Option<SocketAddr>,
    /// Sewio RTLS Studio feed messages.
    pub sewio: Option<SocketAddr>,
    /// Zebra Dart hub lines (one or more per datagram), read by `[adapters.zebra]`.
    pub zebra: Option<SocketAddr>,
    /// OpenRTLS location messages (the master's LS output, sent to UDP port 8787 by default).
    pub openrtls: Option<SocketAddr>,
    /// A gateway's JSON read by `[adapters.generic]` (which must then be configured).
    pub generic: Option<SocketAddr>,
}

impl UdpAdapters {
    /// The address of `vendor`'s listener, if it has one.
    #[must_use]
    pub fn get(&self, vendor: Vendor) -> Option<SocketAddr> {
        match vendor {
            Vendor::Pozyx => self.pozyx,
            Vendor::Quuppa => self.quuppa,
            Vendor::Sewio => self.sewio,
            Vendor::Zebra => self.zebra,
            Vendor::OpenRtls => self.openrtls,
            Vendor::Generic => self.generic,
        }
    }

    /// Gives `vendor` a listener at `address` (`rtls serve --udp-adapter VENDOR=ADDR`).
    pub fn set(&mut self, vendor: Vendor, address: SocketAddr) {
        let slot = match vendor {
            Vendor::Pozyx => &mut self.pozyx,
            Vendor::Quuppa => &mut self.quuppa,
            Vendor::Sewio => &mut self.sewio,
            Vendor::Zebra => &mut self.zebra,
            Vendor::OpenRtls => &mut self.openrtls,
            Vendor::Generic => &mut self.generic,
        };
        *slot = Some(address);
    }
}

impl UdpSection {
    /// Every listener: `None` for our measurement lines, else the vendor, with its address.
    #[must_use]
    pub fn listeners(&self) -> Vec<(Option<Vendor>, SocketAddr)> {
        let mut listeners: Vec<_> = self.listen.map(|a| (None, a)).into_iter().collect();
        listeners.extend(
            Vendor::ALL
                .into_iter()
                .filter_map(|v| self.adapters.get(v).map(|a| (Some(v), a))),
        );
        listeners
    }

    /// Checks that no two listeners share an address (port 0 excepted: each gets its own) and
    /// that a generic listener has `[adapters.generic]` to read by.
    ///
    /// # Errors
    /// [`ConfigError::Invalid`] naming `udp.listen` or `udp.adapters.{vendor}`.
    pub(crate) fn validate(&self, generic_configured: bool) -> Result<(), ConfigError> {
        let field = |vendor: Option<Vendor>| match vendor {
            None => "udp.listen".to_string(),
            Some(v) => format!("udp.adapters.{}", v.name()),
        };
        let listeners = self.listeners();
        for (k, (vendor, address)) in listeners.iter().enumerate() {
            if let Some((other, _)) = listeners[..k].iter().find(|(_, a)| a == address && address.port() != 0) {
                return Err(ConfigError::Invalid {
                    field: field(*vendor),
                    reason: format!(
                        "{address} is {}'s address too: one listener per address (the payload format is chosen by the port)",
                        field(*other)
                    ),
                });
            }
        }
        if self.adapters.generic.is_some() && !generic_configured {
            return Err(ConfigError::Invalid {
                field: "udp.adapters.generic".into(),
                reason: "needs [adapters.generic]: the field paths of the gateway's JSON".into(),
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn listeners_are_listed_by_format_and_checked() {
        let config: UdpSection =
            toml::from_str("listen = \"127.0.0.1:9000\"\n[adapters]\nquuppa = \"127.0.0.1:9001\"\n").unwrap();
        assert_eq!(
            config.listeners(),
            vec![
                (None, "127.0.0.1:9000".parse().unwrap()),
                (Some(Vendor::Quuppa), "127.0.0.1:9001".parse().unwrap())
            ]
        );
        config.validate(false).unwrap();

        let mut twice = config.clone();
        twice.adapters.set(Vendor::Sewio, "127.0.0.1:9001".parse().unwrap());
        let error = twice.validate(false).unwrap_err().to_string();
        assert!(
            error.contains("udp.adapters.sewio") && error.contains("udp.adapters.quuppa"),
            "{error}"
        );

        let mut generic = UdpSection::default();
        generic.adapters.set(Vendor::Generic, "127.0.0.1:0".parse().unwrap());
        assert!(generic
            .validate(false)
            .unwrap_err()
            .to_string()
            .contains("[adapters.generic]"));
        generic.validate(true).unwrap();

        assert!(toml::from_str::<UdpSection>("[adapters]\nacme = \"127.0.0.1:9\"\n").is_err());
        assert!(UdpSection::default().listeners().is_empty(), "off by default");
    }
}
