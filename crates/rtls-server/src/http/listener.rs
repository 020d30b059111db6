//! The HTTP listener: bounded connections — in all and per IP address — and an idle timeout,
//! so that no client can exhaust the server by holding sockets open.
//!
//! A connection over a limit is closed as soon as it is accepted (counted in
//! `rtls_http_connections_refused_total`, logged at most once a second). A connection that
//! moves no byte either way for `idle` is closed: a keep-alive socket nobody uses, a client that
//! stopped halfway through its request. WebSocket connections stay open through the server's
//! pings ([`super::ws`]).

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
    limits: HttpLimits,
    per_ip: Arc<IpSlots>,
    open: Arc<Semaphore>,
    metrics: Arc<Metrics>,
    last_refusal_log: Option<Instant>,
}

impl GuardedListener {
    /// Wraps a bound listener.
    #[must_use]
    pub fn new(inner: TcpListener, limits: HttpLimits, metrics: Arc<Metrics>) -> Self {
        Self {
            inner,
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
    type Io = GuardedStream;
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
            return (GuardedStream::new(stream, slot, permit, self.limits.idle), peer);
        }
    }

    fn local_addr(&self) -> io::Result<Self::Addr> {
        self.inner.local_addr()
    }
}

/// An accepted connection: holds its limit slots while open, and fails with
/// [`io::ErrorKind::TimedOut`] once it has moved no byte for its idle time.
pub struct GuardedStream {
    inner: TcpStream,
    idle_for: Duration,
    idle: Pin<Box<Sleep>>,
    _slot: IpSlot,
    _permit: OwnedSemaphorePermit,
}

impl GuardedStream {
    fn new(inner: TcpStream, slot: IpSlot, permit: OwnedSemaphorePermit, idle_for: Duration) -> Self {
        Self {
            inner,
            idle_for,
            idle: Box::pin(tokio::time::sleep(idle_for)),
            _slot: slot,
            _permit: permit,
        }
    }

    /// Bytes moved: the idle time starts again.
    fn active(&mut self) {
        let deadline = tokio::time::Instant::now() + self.idle_for;
        self.idle.as_mut().reset(deadline);
    }

    /// Waiting for the peer: an error once the idle time is over.
    fn check_idle(&mut self, cx: &mut Context<'_>) -> Poll<io::Error> {
        match self.idle.as_mut().poll(cx) {
            Poll::Ready(()) => Poll::Ready(io::Error::new(
                io::ErrorKind::TimedOut,
                format!("no byte moved for {:?}", self.idle_for),
            )),
            Poll::Pending => Poll::Pending,
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
