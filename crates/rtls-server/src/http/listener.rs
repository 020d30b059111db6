//! The HTTP listener: bounded connections — in all and per IP address — an idle timeout, so
//! that no client can exhaust the server by holding sockets open, and TLS (HTTPS, WSS) when a
//! certificate is configured ([`crate::tls`]). The TLS handshake runs in the connection's own
//! task (a slow client cannot hold up the accept loop) and is bounded by the idle timeout.
//!
//! A connection over a limit is closed as soon as it is accepted (counted in
//! `rtls_http_connections_refused_total`, logged at most once a second). A connection that
//! moves no byte either way for `idle` is closed: a keep-alive socket nobody uses, a client that
//! stopped halfway through its request. WebSocket connections stay open through the server's
//! pings (every 30 s).

use std::future::Future;
use std::io;
use std::net::SocketAddr;
use std::pin::Pin;
use std::sync::Arc;
use std::task::{Context, Poll};
use std::time::{Duration, Instant};

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{OwnedSemaphorePermit, Semaphore};
use tokio::time::Sleep;
use tokio_rustls::server::TlsStream;
use tokio_rustls::{Accept, TlsAcceptor};

use crate::limits::{IpSlot, IpSlots};
use crate::metrics::Metrics;

/// How long to wait before accepting again after `accept` failed (e.g. out of file
/// descriptors), so that the loop does not spin.
const ACCEPT_RETRY_DELAY: Duration = Duration::from_millis(100);

/// The limits of the HTTP listener.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HttpLimits {
    /// Open connections at most.
    pub max_connections: usize,
    /// Open connections of one IP address at most.
    pub max_connections_per_ip: usize,
    /// A connection moving no byte for this long is closed.
    pub idle: Duration,
}

impl Default for HttpLimits {
    fn default() -> Self {
        Self {
            max_connections: 4096,
            max_connections_per_ip: 256,
            idle: Duration::from_secs(120),
        }
    }
}

/// A TCP listener that enforces [`HttpLimits`]; serve it with `axum::serve`.
pub struct GuardedListener {
    inner: TcpListener,
    tls: Option<TlsAcceptor>,
    limits: HttpLimits,
    per_ip: Arc<IpSlots>,
    open: Arc<Semaphore>,
    metrics: Arc<Metrics>,
    last_refusal_log: Option<Instant>,
}

impl GuardedListener {
    /// Wraps a bound listener; with `tls`, every connection is HTTPS.
    #[must_use]
    pub fn new(inner: TcpListener, limits: HttpLimits, tls: Option<TlsAcceptor>, metrics: Arc<Metrics>) -> Self {
        Self {
            inner,
            tls,
            per_ip: Arc::default(),
            open: Arc::new(Semaphore::new(limits.max_connections)),
            limits,
            metrics,
            last_refusal_log: None,
        }
    }

    fn refuse(&mut self, peer: SocketAddr, why: &'static str) {
        self.metrics
            .http_connections_refused
            .get_or_create(&vec![("reason".into(), why.into())])
            .inc();
        if self
            .last_refusal_log
            .is_none_or(|at| at.elapsed() >= Duration::from_secs(1))
        {
            self.last_refusal_log = Some(Instant::now());
            tracing::warn!(%peer, reason = why, "http: connection refused (limit reached)");
        }
    }
}

impl axum::serve::Listener for GuardedListener {
    type Io = ServedStream;
    type Addr = SocketAddr;

    async fn accept(&mut self) -> (Self::Io, Self::Addr) {
        loop {
            let (stream, peer) = match self.inner.accept().await {
                Ok(accepted) => accepted,
                Err(error) => {
                    tracing::warn!(%error, "http: accept failed");
                    tokio::time::sleep(ACCEPT_RETRY_DELAY).await;
                    continue;
                }
            };
            let Some(slot) = self.per_ip.take(peer.ip(), self.limits.max_connections_per_ip) else {
                self.refuse(peer, "per_ip");
                continue;
            };
            let Ok(permit) = Arc::clone(&self.open).try_acquire_owned() else {
                self.refuse(peer, "total");
                continue;
            };
            let _ = stream.set_nodelay(true);
            let guarded = GuardedStream::new(stream, slot, permit, self.limits.idle);
            let served = match &self.tls {
                Some(acceptor) => ServedStream::Tls(TlsState::Handshake(Box::new(acceptor.accept(guarded)))),
                None => ServedStream::Plain(guarded),
            };
            return (served, peer);
        }
    }

    fn local_addr(&self) -> io::Result<Self::Addr> {
        self.inner.local_addr()
    }
}

/// An accepted connection: holds its limit slots while open, and fails with
/// [`io::ErrorKind::TimedOut`] once it has moved no byte for its idle time.
///
/// Bytes moving only note the time (`last_active`); the timer is re-armed when it fires, not
/// on every read and write.
pub struct GuardedStream {
    inner: TcpStream,
    idle_for: Duration,
    idle: Pin<Box<Sleep>>,
    last_active: tokio::time::Instant,
    _slot: IpSlot,
    _permit: OwnedSemaphorePermit,
}

impl GuardedStream {
    fn new(inner: TcpStream, slot: IpSlot, permit: OwnedSemaphorePermit, idle_for: Duration) -> Self {
        Self {
            inner,
            idle_for,
            idle: Box::pin(tokio::time::sleep(idle_for)),
            last_active: tokio::time::Instant::now(),
            _slot: slot,
            _permit: permit,
        }
    }

    /// Bytes moved: the idle time starts again.
    fn active(&mut self) {
        self.last_active = tokio::time::Instant::now();
    }

    /// Waiting for the peer: an error once `idle_for` has passed since bytes last moved.
    fn check_idle(&mut self, cx: &mut Context<'_>) -> Poll<io::Error> {
        loop {
            if self.idle.as_mut().poll(cx).is_pending() {
                return Poll::Pending;
            }
            // deadline = last activity + idle time; re-arm while it lies ahead
            let deadline = self.last_active + self.idle_for;
            if deadline <= tokio::time::Instant::now() {
                return Poll::Ready(io::Error::new(
                    io::ErrorKind::TimedOut,
                    format!("no byte moved for {:?}", self.idle_for),
                ));
            }
            self.idle.as_mut().reset(deadline);
        }
    }
}

impl AsyncRead for GuardedStream {
    fn poll_read(mut self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &mut ReadBuf<'_>) -> Poll<io::Result<()>> {
        let before = buf.filled().len();
        match Pin::new(&mut self.inner).poll_read(cx, buf) {
            Poll::Ready(result) => {
                if buf.filled().len() > before {
                    self.active();
                }
                Poll::Ready(result)
            }
            Poll::Pending => self.check_idle(cx).map(Err),
        }
    }
}

impl AsyncWrite for GuardedStream {
    fn poll_write(mut self: Pin<&mut Self>, cx: &mut Context<'_>, data: &[u8]) -> Poll<io::Result<usize>> {
        match Pin::new(&mut self.inner).poll_write(cx, data) {
            Poll::Ready(Ok(written)) => {
                if written > 0 {
                    self.active();
                }
                Poll::Ready(Ok(written))
            }
            Poll::Ready(Err(error)) => Poll::Ready(Err(error)),
            Poll::Pending => self.check_idle(cx).map(Err),
        }
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_shutdown(cx)
    }

    fn poll_write_vectored(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        match Pin::new(&mut self.inner).poll_write_vectored(cx, bufs) {
            Poll::Ready(Ok(written)) => {
                if written > 0 {
                    self.active();
                }
                Poll::Ready(Ok(written))
            }
            Poll::Ready(Err(error)) => Poll::Ready(Err(error)),
            Poll::Pending => self.check_idle(cx).map(Err),
        }
    }

    fn is_write_vectored(&self) -> bool {
        self.inner.is_write_vectored()
    }
}

/// A connection as the HTTP server reads it: plain, or TLS once its handshake is done.
pub enum ServedStream {
    /// HTTP.
    Plain(GuardedStream),
    /// HTTPS.
    Tls(TlsState),
}

/// Where a TLS connection is.
pub enum TlsState {
    /// The handshake is under way.
    Handshake(Box<Accept<GuardedStream>>),
    /// Established.
    Ready(Box<TlsStream<GuardedStream>>),
    /// The handshake failed (the connection is dropped).
    Failed,
}

impl ServedStream {
    /// Drives a TLS handshake to its end; ready at once for a plain connection.
    fn poll_handshake(&mut self, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        let Self::Tls(state) = self else {
            return Poll::Ready(Ok(()));
        };
        loop {
            match state {
                TlsState::Handshake(accept) => match Pin::new(accept.as_mut()).poll(cx) {
                    Poll::Ready(Ok(stream)) => *state = TlsState::Ready(Box::new(stream)),
                    Poll::Ready(Err(error)) => {
                        tracing::debug!(%error, "http: TLS handshake failed");
                        *state = TlsState::Failed;
                        return Poll::Ready(Err(error));
                    }
                    Poll::Pending => return Poll::Pending,
                },
                TlsState::Ready(_) => return Poll::Ready(Ok(())),
                TlsState::Failed => {
                    return Poll::Ready(Err(io::Error::new(
                        io::ErrorKind::NotConnected,
                        "the TLS handshake failed",
                    )))
                }
            }
        }
    }
}

/// Runs `$call` on the established stream, after the handshake.
macro_rules! on_stream {
    ($self:ident, $cx:ident, |$stream:ident| $call:expr) => {{
        let this = $self.get_mut();
        match this.poll_handshake($cx) {
            Poll::Ready(Ok(())) => {}
            Poll::Ready(Err(error)) => return Poll::Ready(Err(error)),
            Poll::Pending => return Poll::Pending,
        }
        match this {
            ServedStream::Plain($stream) => {
                let $stream = Pin::new($stream);
                $call
            }
            ServedStream::Tls(TlsState::Ready(stream)) => {
                let $stream = Pin::new(stream.as_mut());
                $call
            }
            ServedStream::Tls(_) => Poll::Ready(Err(io::Error::new(io::ErrorKind::NotConnected, "no TLS session"))),
        }
    }};
}

impl AsyncRead for ServedStream {
    fn poll_read(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &mut ReadBuf<'_>) -> Poll<io::Result<()>> {
        on_stream!(self, cx, |stream| stream.poll_read(cx, buf))
    }
}

impl AsyncWrite for ServedStream {
    fn poll_write(self: Pin<&mut Self>, cx: &mut Context<'_>, data: &[u8]) -> Poll<io::Result<usize>> {
        on_stream!(self, cx, |stream| stream.poll_write(cx, data))
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        on_stream!(self, cx, |stream| stream.poll_flush(cx))
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        on_stream!(self, cx, |stream| stream.poll_shutdown(cx))
    }
}

/// The peer address of a connection, as handlers and middleware see it
/// (`ConnectInfo<Peer>`, with `into_make_service_with_connect_info::<Peer>()`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Peer(pub SocketAddr);

impl axum::extract::connect_info::Connected<axum::serve::IncomingStream<'_, GuardedListener>> for Peer {
    fn connect_info(stream: axum::serve::IncomingStream<'_, GuardedListener>) -> Self {
        Self(*stream.remote_addr())
    }
}
