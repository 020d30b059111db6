//! Framing MQTT 3.1.1 packets on a byte stream with rumqttc's codec, plus the checks the codec
//! leaves to a server: the reserved flag bits of the fixed header and the protocol version of a
//! CONNECT.

use bytes::BytesMut;
use rumqttc::mqttbytes::v4::{
    ConnAck, Connect, Disconnect, Packet, PingReq, PingResp, PubAck, PubComp, PubRec, PubRel, Publish, SubAck,
    Subscribe, UnsubAck, Unsubscribe,
};
use rumqttc::mqttbytes::{self, check};

/// What the start of an input buffer holds.
#[derive(Debug)]
pub(crate) enum Next {
    /// Not a whole packet yet: at least this many more bytes are needed.
    Incomplete {
        /// Bytes still missing (a lower bound).
        needed_bytes: usize,
    },
    /// One decoded packet, removed from the buffer.
    Packet(Packet),
}

/// Why the bytes at the start of an input buffer are not an acceptable packet. Each one closes
/// the connection.
#[derive(Debug, thiserror::Error)]
pub(crate) enum FrameError {
    /// The fixed header announces more than the configured limit.
    #[error("packet of {remaining_bytes} bytes exceeds the limit of {limit_bytes} bytes")]
    Oversize {
        /// The packet's remaining length (variable header + payload).
        remaining_bytes: usize,
        /// The configured limit.
        limit_bytes: usize,
    },
    /// The fixed header's flag bits are not the ones MQTT 3.1.1 §2.2.2 prescribes.
    #[error("packet type {packet_type} with reserved flags {flags:#06b} (expected {expected:#06b})")]
    ReservedFlags {
        /// The packet type number (1 = CONNECT … 14 = DISCONNECT).
        packet_type: u8,
        /// The flag bits found.
        flags: u8,
        /// The flag bits required.
        expected: u8,
    },
    /// A CONNECT of a protocol version other than 3.1.1 (level 4): MQTT 3.1 (`MQIsdp`, level 3)
    /// or MQTT 5 (level 5). Answered with CONNACK "unacceptable protocol version".
    #[error("protocol {name:?} level {level} is not supported (only MQTT 3.1.1, level 4)")]
    UnsupportedProtocol {
        /// The protocol name of the CONNECT.
        name: String,
        /// The protocol level of the CONNECT.
        level: u8,
    },
    /// The codec could not decode the packet.
    #[error("malformed packet: {0}")]
    Malformed(mqttbytes::Error),
}

/// Decodes the next packet at the start of `buf`, if it holds a whole one.
///
/// `max_packet_bytes` bounds the remaining length announced in the fixed header; a larger packet
/// is refused as soon as its fixed header has arrived, before its body is buffered.
///
/// # Errors
/// [`FrameError`] when the bytes are not an acceptable packet; the buffer is then in an
/// undefined state and the connection must be closed.
pub(crate) fn next_packet(buf: &mut BytesMut, max_packet_bytes: usize) -> Result<Next, FrameError> {
    match check(buf.iter(), max_packet_bytes) {
        Ok(_) => {}
        Err(mqttbytes::Error::InsufficientBytes(needed_bytes)) => return Ok(Next::Incomplete { needed_bytes }),
        Err(mqttbytes::Error::PayloadSizeLimitExceeded(remaining_bytes)) => {
            return Err(FrameError::Oversize {
                remaining_bytes,
                limit_bytes: max_packet_bytes,
            })
        }
        Err(other) => return Err(FrameError::Malformed(other)),
    }
    // `check` succeeded, so the buffer holds at least the first byte.
    let first_byte = buf.first().copied().unwrap_or_default();
    check_reserved_flags(first_byte)?;
    if first_byte >> 4 == 1 {
        check_connect_protocol(buf)?;
    }
    Packet::read(buf, max_packet_bytes)
        .map(Next::Packet)
        .map_err(FrameError::Malformed)
}

/// Checks the flag bits of a fixed header's first byte (MQTT 3.1.1 §2.2.2): PUBLISH carries its
/// own flags (QoS 3 is refused by the codec), SUBSCRIBE, UNSUBSCRIBE and PUBREL must have
/// `0010`, every other packet `0000`.
fn check_reserved_flags(first_byte: u8) -> Result<(), FrameError> {
    let packet_type = first_byte >> 4;
    let flags = first_byte & 0x0F;
    let expected = match packet_type {
        3 => return Ok(()),
        6 | 8 | 10 => 0b0010,
        _ => 0b0000,
    };
    if flags == expected {
        Ok(())
    } else {
        Err(FrameError::ReservedFlags {
            packet_type,
            flags,
            expected,
        })
    }
}

/// Reads the protocol name and level of the whole CONNECT packet at the start of `frame` and
/// refuses any but MQTT 3.1.1. The codec would decode an MQTT 5 CONNECT as if it were 3.1.1.
fn check_connect_protocol(frame: &[u8]) -> Result<(), FrameError> {
    // The fixed header: one byte, then 1–4 bytes of remaining length (the last without bit 7).
    let length_bytes = frame
        .iter()
        .skip(1)
        .take(4)
        .take_while(|byte| *byte & 0x80 != 0)
        .count()
        + 1;
    let variable_header = frame.get(1 + length_bytes..).unwrap_or_default();
    let name_length = match variable_header.get(..2) {
        Some(&[high, low]) => usize::from(u16::from_be_bytes([high, low])),
        _ => return Err(FrameError::Malformed(mqttbytes::Error::MalformedPacket)),
    };
    let name = variable_header
        .get(2..2 + name_length)
        .ok_or(FrameError::Malformed(mqttbytes::Error::MalformedPacket))?;
    let level = *variable_header
        .get(2 + name_length)
        .ok_or(FrameError::Malformed(mqttbytes::Error::MalformedPacket))?;
    match (name, level) {
        (b"MQTT", 4) => Ok(()),
        (b"MQTT" | b"MQIsdp", level) => Err(FrameError::UnsupportedProtocol {
            name: String::from_utf8_lossy(name).into_owned(),
            level,
        }),
        _ => Err(FrameError::Malformed(mqttbytes::Error::InvalidProtocol)),
    }
}

/// Appends the encoding of `packet` to `out`.
///
/// # Errors
/// The codec's error when the packet cannot be encoded (a payload over 256 MiB, a QoS 1
/// PUBLISH with packet id 0).
pub(crate) fn encode(packet: &Packet, out: &mut BytesMut) -> Result<(), mqttbytes::Error> {
    match packet {
        Packet::Connect(connect) => Connect::write(connect, out),
        Packet::ConnAck(connack) => ConnAck::write(connack, out),
        Packet::Publish(publish) => Publish::write(publish, out),
        Packet::PubAck(puback) => PubAck::write(puback, out),
        Packet::PubRec(pubrec) => PubRec::write(pubrec, out),
        Packet::PubRel(pubrel) => PubRel::write(pubrel, out),
        Packet::PubComp(pubcomp) => PubComp::write(pubcomp, out),
        Packet::Subscribe(subscribe) => Subscribe::write(subscribe, out),
        Packet::SubAck(suback) => SubAck::write(suback, out),
        Packet::Unsubscribe(unsubscribe) => Unsubscribe::write(unsubscribe, out),
        Packet::UnsubAck(unsuback) => UnsubAck::write(unsuback, out),
        Packet::PingReq => PingReq.write(out),
        Packet::PingResp => PingResp.write(out),
        Packet::Disconnect => Disconnect.write(out),
    }
    .map(|_| ())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rumqttc::mqttbytes::QoS;

    fn encoded(packet: &Packet) -> BytesMut {
        let mut out = BytesMut::new();
        encode(packet, &mut out).expect("encodable test packet");
        out
    }

    fn connect_bytes(name: &[u8], level: u8) -> BytesMut {
        // CONNECT with clean session, keep-alive 10 s, client id "c".
        let mut body = Vec::new();
        body.extend_from_slice(&u16::try_from(name.len()).expect("short name").to_be_bytes());
        body.extend_from_slice(name);
        body.extend_from_slice(&[level, 0b0000_0010, 0, 10, 0, 1, b'c']);
        let mut frame = BytesMut::new();
        frame.extend_from_slice(&[0x10, u8::try_from(body.len()).expect("short body")]);
        frame.extend_from_slice(&body);
        frame
    }

    #[test]
    fn a_packet_split_across_reads_is_decoded_once_whole_and_leaves_the_rest() {
        let publish = Packet::Publish(Publish::new(
            "rtls/v1/measurements/r1",
            QoS::AtLeastOnce,
            "x".repeat(300),
        ));
        let mut with_pkid = publish.clone();
        if let Packet::Publish(p) = &mut with_pkid {
            p.pkid = 7;
        }
        let mut stream = encoded(&with_pkid);
        stream.extend_from_slice(&encoded(&Packet::PingReq));
        let whole = stream.clone();

        let mut buf = BytesMut::from(&whole[..10]);
        match next_packet(&mut buf, 1024) {
            Ok(Next::Incomplete { needed_bytes }) => assert!(needed_bytes > 0),
            other => panic!("expected Incomplete, got {other:?}"),
        }
        assert_eq!(buf.len(), 10, "an incomplete packet stays in the buffer");

        let mut buf = whole;
        match next_packet(&mut buf, 1024) {
            Ok(Next::Packet(packet)) => assert_eq!(packet, with_pkid),
            other => panic!("expected the PUBLISH, got {other:?}"),
        }
        match next_packet(&mut buf, 1024) {
            Ok(Next::Packet(Packet::PingReq)) => {}
            other => panic!("expected PINGREQ, got {other:?}"),
        }
        assert!(buf.is_empty());
    }

    #[test]
    fn an_oversize_packet_is_refused_from_its_fixed_header_alone() {
        // Fixed header of a PUBLISH announcing 2000 bytes, none of which has arrived.
        let mut buf = BytesMut::from(&[0x30, 0xD0, 0x0F][..]);
        assert_eq!(
            next_packet(&mut buf, 1000).unwrap_err().to_string(),
            FrameError::Oversize {
                remaining_bytes: 2000,
                limit_bytes: 1000
            }
            .to_string()
        );
    }

    #[test]
    fn reserved_flags_are_checked_per_packet_type() {
        // SUBSCRIBE with flags 0000 instead of 0010.
        let mut subscribe = encoded(&Packet::Subscribe(Subscribe::new("a/b", QoS::AtMostOnce)));
        subscribe[0] = 0x80;
        assert_eq!(
            next_packet(&mut subscribe, 1024).unwrap_err().to_string(),
            FrameError::ReservedFlags {
                packet_type: 8,
                flags: 0,
                expected: 0b0010
            }
            .to_string()
        );
        // PINGREQ with a flag bit set.
        let mut ping = BytesMut::from(&[0xC1, 0x00][..]);
        assert!(matches!(
            next_packet(&mut ping, 1024),
            Err(FrameError::ReservedFlags { packet_type: 12, .. })
        ));
        // A correct SUBSCRIBE passes.
        let mut subscribe = encoded(&Packet::Subscribe(Subscribe::new("a/b", QoS::AtMostOnce)));
        assert!(matches!(
            next_packet(&mut subscribe, 1024),
            Ok(Next::Packet(Packet::Subscribe(_)))
        ));
    }

    #[test]
    fn only_mqtt_3_1_1_connects_are_accepted() {
        let mut v311 = connect_bytes(b"MQTT", 4);
        match next_packet(&mut v311, 1024) {
            Ok(Next::Packet(Packet::Connect(connect))) => assert_eq!(connect.client_id, "c"),
            other => panic!("expected the CONNECT, got {other:?}"),
        }
        for (name, level) in [(&b"MQTT"[..], 5), (&b"MQIsdp"[..], 3)] {
            let mut buf = connect_bytes(name, level);
            assert_eq!(
                next_packet(&mut buf, 1024).unwrap_err().to_string(),
                FrameError::UnsupportedProtocol {
                    name: String::from_utf8_lossy(name).into_owned(),
                    level
                }
                .to_string()
            );
        }
        let mut not_mqtt = connect_bytes(b"HTTP", 4);
        assert!(matches!(
            next_packet(&mut not_mqtt, 1024).unwrap_err(),
            FrameError::Malformed(mqttbytes::Error::InvalidProtocol)
        ));
    }

    #[test]
    fn truncated_and_garbage_bodies_are_errors_not_panics() {
        // Every prefix of a CONNECT whose remaining length claims the whole body, and a few
        // garbage streams: the decoder must answer Incomplete or an error, never panic.
        let connect = connect_bytes(b"MQTT", 4);
        for cut in 2..connect.len() {
            let mut body = connect[..cut].to_vec();
            body[1] = u8::try_from(cut - 2).expect("short");
            let mut buf = BytesMut::from(&body[..]);
            let _ = next_packet(&mut buf, 1024);
        }
        for garbage in [
            &[0xFFu8, 0xFF, 0xFF, 0xFF, 0xFF][..],
            &[0x82, 0x01, 0x00],
            &[0xA2, 0x03, 0x00, 0x01, 0x00],
        ] {
            let mut buf = BytesMut::from(garbage);
            assert!(
                !matches!(next_packet(&mut buf, 1024), Ok(Next::Packet(_))),
                "{garbage:?} decoded as a packet"
            );
        }
    }
}
