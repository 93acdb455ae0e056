//! A fault-injecting TCP proxy (tokio) to put between workers and the master.
//!
//! Every accepted connection is piped to the upstream address in both directions;
//! each chunk read is passed through the proxy's current [`LinkMode`], which the test or
//! the soak changes at any time: delay, drop, truncate, corrupt, stall (the peer sees
//! an open but silent socket) or cut. It can also capture every byte it forwards (all
//! together, and per connection and direction), so a test can prove what never crosses
//! the wire, and change one chosen byte of the next connection ([`Tamper`]), as an
//! attacker on the path would. The proxy runs on
//! its own thread and runtime, so synchronous tests and the soak command drive it alike.

use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::Duration;

use rand::{Rng, SeedableRng};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::tcp::{OwnedReadHalf, OwnedWriteHalf};
use tokio::net::{TcpListener, TcpStream};
use tokio_util::sync::CancellationToken;

/// Most bytes kept by [`Proxy::captured`]; capture stops there (bounded memory).
pub const MAX_CAPTURE: usize = 64 * 1024 * 1024;
/// How often a stalled pipe looks whether the stall is over.
const STALL_POLL: Duration = Duration::from_millis(20);

/// What the proxy does to the bytes it forwards.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkMode {
    /// Forward unchanged.
    Pass,
    /// Hold each chunk this long before forwarding it.
    Delay(Duration),
    /// Discard each chunk read (the stream loses its framing).
    Drop,
    /// Forward half of the next chunk, then close the connection.
    Truncate,
    /// Flip one random byte in each chunk.
    Corrupt,
    /// Stop reading and forwarding, keeping both sockets open (half-open link).
    Stall,
    /// Close every connection as soon as it sends anything (new ones included).
    Cut,
}

impl LinkMode {
    /// A short name for reports (`faults` by kind).
    pub fn name(&self) -> &'static str {
        match self {
            LinkMode::Pass => "pass",
            LinkMode::Delay(_) => "delay",
            LinkMode::Drop => "drop",
            LinkMode::Truncate => "truncate",
            LinkMode::Corrupt => "corrupt",
            LinkMode::Stall => "stall",
            LinkMode::Cut => "cut",
        }
    }
}

/// Which way bytes flow through a pipe.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// From the connecting peer (a worker) to the upstream (the master).
    Up,
    /// From the upstream back to the peer.
    Down,
}

/// One byte the proxy changes on the next connection it accepts: the byte at offset `at`
/// of direction `dir` (counted from that connection's first byte) is XORed with `xor`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tamper {
    pub dir: Direction,
    pub at: u64,
    pub xor: u8,
}

/// Counters of what the proxy did.
#[derive(Debug, Default)]
pub struct ProxyStats {
    pub connections: AtomicU64,
    pub bytes_up: AtomicU64,
    pub bytes_down: AtomicU64,
    /// Chunks that were delayed, dropped, corrupted or truncated, and connections cut.
    pub chunks_faulted: AtomicU64,
    pub connections_cut: AtomicU64,
}

struct Shared {
    mode: Mutex<LinkMode>,
    upstream: Mutex<SocketAddr>,
    /// Cancelled by [`Proxy::cut_all`]; replaced by a fresh one for later connections.
    generation: Mutex<CancellationToken>,
    capture: Mutex<Option<Capture>>,
    /// For the next connection accepted, then cleared.
    tamper: Mutex<Option<Tamper>>,
    stats: ProxyStats,
}

/// What was forwarded while capturing: everything in order, and each connection's two
/// directions apart (indexed by [`Direction`]: up, down).
#[derive(Default)]
struct Capture {
    all: Vec<u8>,
    connections: Vec<[Vec<u8>; 2]>,
}

/// A running proxy; dropping it closes the listening socket and every connection.
pub struct Proxy {
    local_addr: SocketAddr,
    shared: Arc<Shared>,
    stop: CancellationToken,
    thread: Option<JoinHandle<()>>,
}

impl Proxy {
    /// Listens on an ephemeral 127.0.0.1 port and forwards to `upstream`.
    pub fn start(upstream: SocketAddr) -> std::io::Result<Self> {
        let socket = std::net::TcpListener::bind("127.0.0.1:0")?;
        socket.set_nonblocking(true)?;
        let local_addr = socket.local_addr()?;
        let shared = Arc::new(Shared {
            mode: Mutex::new(LinkMode::Pass),
            upstream: Mutex::new(upstream),
            generation: Mutex::new(CancellationToken::new()),
            capture: Mutex::new(None),
            tamper: Mutex::new(None),
            stats: ProxyStats::default(),
        });
        let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build()?;
        let stop = CancellationToken::new();
        let (s, st) = (shared.clone(), stop.clone());
        let thread =
            std::thread::Builder::new().name("gridlight-proxy".into()).spawn(move || {
                runtime.block_on(async move {
                    match TcpListener::from_std(socket) {
                        Ok(listener) => accept_loop(listener, s, st).await,
                        Err(e) => tracing::error!(cause = %e, "proxy cannot listen"),
                    }
                })
            })?;
        Ok(Self { local_addr, shared, stop, thread: Some(thread) })
    }

    /// Where peers connect instead of the upstream.
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// Changes what happens to every byte from now on, on every connection.
    pub fn set_mode(&self, mode: LinkMode) {
        *lock(&self.shared.mode) = mode;
    }

    pub fn mode(&self) -> LinkMode {
        *lock(&self.shared.mode)
    }

    /// Where new connections go (a restarted master may listen elsewhere).
    pub fn set_upstream(&self, upstream: SocketAddr) {
        *lock(&self.shared.upstream) = upstream;
    }

    /// Closes every open connection now; later ones are served as usual.
    pub fn cut_all(&self) {
        let old = std::mem::take(&mut *lock(&self.shared.generation));
        old.cancel();
    }

    /// Starts keeping a copy of every byte forwarded, both ways (up to [`MAX_CAPTURE`]).
    pub fn start_capture(&self) {
        *lock(&self.shared.capture) = Some(Capture::default());
    }

    /// The bytes captured so far, both directions of every connection in order.
    pub fn captured(&self) -> Vec<u8> {
        lock(&self.shared.capture).as_ref().map(|c| c.all.clone()).unwrap_or_default()
    }

    /// The bytes captured so far per connection accepted since the capture started:
    /// `[up, down]` each.
    pub fn captured_connections(&self) -> Vec<[Vec<u8>; 2]> {
        lock(&self.shared.capture).as_ref().map(|c| c.connections.clone()).unwrap_or_default()
    }

    /// Changes one byte of the next connection accepted (see [`Tamper`]).
    pub fn tamper_next(&self, tamper: Tamper) {
        *lock(&self.shared.tamper) = Some(tamper);
    }

    pub fn stats(&self) -> &ProxyStats {
        &self.shared.stats
    }
}

impl Drop for Proxy {
    fn drop(&mut self) {
        self.stop.cancel();
        self.cut_all();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// A poisoned lock only means a test thread panicked; the data is still usable.
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

async fn accept_loop(listener: TcpListener, shared: Arc<Shared>, stop: CancellationToken) {
    loop {
        let accepted = tokio::select! {
            _ = stop.cancelled() => return,
            a = listener.accept() => a,
        };
        let (peer, addr) = match accepted {
            Ok(a) => a,
            Err(e) => {
                tracing::warn!(cause = %e, "proxy accept failed");
                continue;
            }
        };
        shared.stats.connections.fetch_add(1, Ordering::Relaxed);
        let tamper = lock(&shared.tamper).take();
        let index = lock(&shared.capture).as_mut().map(|c| {
            c.connections.push(Default::default());
            c.connections.len() - 1
        });
        let token = lock(&shared.generation).child_token();
        let upstream = *lock(&shared.upstream);
        let shared = shared.clone();
        tokio::spawn(async move {
            let Ok(up) = TcpStream::connect(upstream).await else {
                tracing::debug!(%addr, %upstream, "proxy: upstream unreachable, closing peer");
                return;
            };
            let _ = (peer.set_nodelay(true), up.set_nodelay(true));
            let (pr, pw) = peer.into_split();
            let (ur, uw) = up.into_split();
            let conn = token.child_token();
            let up = Pipe { dir: Direction::Up, index, tamper, conn: conn.clone() };
            let down = Pipe { dir: Direction::Down, index, tamper, conn: conn.clone() };
            let a = tokio::spawn(pipe(pr, uw, up, shared.clone()));
            let b = tokio::spawn(pipe(ur, pw, down, shared));
            let _ = tokio::join!(a, b);
        });
    }
}

/// One direction of one connection.
struct Pipe {
    dir: Direction,
    /// The connection's place in the capture, if capturing.
    index: Option<usize>,
    tamper: Option<Tamper>,
    /// Ends both directions.
    conn: CancellationToken,
}

/// Forwards one direction of one connection through the current mode. When it ends,
/// it ends the other direction too (`conn`), as a real link failure would.
async fn pipe(mut from: OwnedReadHalf, mut to: OwnedWriteHalf, p: Pipe, shared: Arc<Shared>) {
    let Pipe { dir, index, conn, .. } = p;
    let tamper = p.tamper.filter(|t| t.dir == dir);
    let mut rng = rand::rngs::StdRng::from_entropy();
    let mut buf = vec![0u8; 64 * 1024];
    let mut offset = 0u64;
    loop {
        if *lock(&shared.mode) == LinkMode::Stall {
            tokio::select! {
                _ = conn.cancelled() => break,
                _ = tokio::time::sleep(STALL_POLL) => continue,
            }
        }
        let n = tokio::select! {
            _ = conn.cancelled() => break,
            r = from.read(&mut buf) => match r { Ok(0) | Err(_) => break, Ok(n) => n },
        };
        let mode = *lock(&shared.mode);
        let chunk = &mut buf[..n];
        if let Some(t) = tamper.filter(|t| (offset..offset + n as u64).contains(&t.at)) {
            chunk[(t.at - offset) as usize] ^= t.xor;
        }
        offset += n as u64;
        let faulted = &shared.stats.chunks_faulted;
        match mode {
            LinkMode::Pass | LinkMode::Stall => {}
            LinkMode::Delay(d) => {
                faulted.fetch_add(1, Ordering::Relaxed);
                tokio::time::sleep(d).await;
            }
            LinkMode::Drop => {
                faulted.fetch_add(1, Ordering::Relaxed);
                continue;
            }
            LinkMode::Corrupt => {
                faulted.fetch_add(1, Ordering::Relaxed);
                let i = rng.gen_range(0..n);
                chunk[i] ^= rng.gen_range(1..=255u8);
            }
            LinkMode::Truncate => {
                faulted.fetch_add(1, Ordering::Relaxed);
                let half = n / 2;
                record(&shared, dir, index, &chunk[..half]);
                let _ = to.write_all(&chunk[..half]).await;
                break;
            }
            LinkMode::Cut => {
                shared.stats.connections_cut.fetch_add(1, Ordering::Relaxed);
                break;
            }
        }
        record(&shared, dir, index, chunk);
        if to.write_all(chunk).await.is_err() {
            break;
        }
    }
    let _ = to.shutdown().await;
    conn.cancel();
}

fn record(shared: &Shared, dir: Direction, index: Option<usize>, bytes: &[u8]) {
    let counter = match dir {
        Direction::Up => &shared.stats.bytes_up,
        Direction::Down => &shared.stats.bytes_down,
    };
    counter.fetch_add(bytes.len() as u64, Ordering::Relaxed);
    if let Some(cap) = lock(&shared.capture).as_mut() {
        let room = MAX_CAPTURE.saturating_sub(cap.all.len());
        let kept = &bytes[..bytes.len().min(room)];
        cap.all.extend_from_slice(kept);
        if let Some(conn) = index.and_then(|i| cap.connections.get_mut(i)) {
            conn[dir as usize].extend_from_slice(kept);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::{Read, Write};

    /// An upstream that echoes everything back.
    fn echo_server() -> SocketAddr {
        let l = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
        let addr = l.local_addr().expect("addr");
        std::thread::spawn(move || {
            for s in l.incoming().flatten() {
                std::thread::spawn(move || {
                    let mut s = s;
                    let mut b = [0u8; 1024];
                    while let Ok(n) = s.read(&mut b) {
                        if n == 0 || s.write_all(&b[..n]).is_err() {
                            break;
                        }
                    }
                });
            }
        });
        addr
    }

    fn client(p: &Proxy) -> std::net::TcpStream {
        let s = std::net::TcpStream::connect(p.local_addr()).expect("connect");
        s.set_read_timeout(Some(Duration::from_secs(5))).expect("timeout");
        s
    }

    /// Reads until EOF or error; what arrived.
    fn read_all(s: &mut std::net::TcpStream) -> Vec<u8> {
        let mut out = Vec::new();
        let mut b = [0u8; 1024];
        while let Ok(n) = s.read(&mut b) {
            if n == 0 {
                break;
            }
            out.extend_from_slice(&b[..n]);
        }
        out
    }

    #[test]
    fn passes_and_captures_both_ways() {
        let p = Proxy::start(echo_server()).expect("proxy");
        p.start_capture();
        let mut s = client(&p);
        s.write_all(b"hello").expect("write");
        let mut got = [0u8; 5];
        s.read_exact(&mut got).expect("echo");
        assert_eq!(&got, b"hello");
        // "hello" went up and came back down.
        assert_eq!(p.captured().windows(5).filter(|w| w == b"hello").count(), 2);
    }

    #[test]
    fn corrupt_changes_bytes_and_truncate_closes() {
        let p = Proxy::start(echo_server()).expect("proxy");
        p.set_mode(LinkMode::Corrupt);
        let mut s = client(&p);
        s.write_all(&[0u8; 8]).expect("write");
        let mut got = [0u8; 8];
        s.read_exact(&mut got).expect("echo");
        assert_ne!(got, [0u8; 8], "corrupt mode forwarded the bytes unchanged");

        p.set_mode(LinkMode::Truncate);
        let mut s = client(&p);
        s.write_all(b"0123456789").expect("write");
        let got = read_all(&mut s);
        assert!(got.len() <= 5, "more than half of a truncated chunk came back: {got:?}");
    }

    #[test]
    fn tamper_changes_one_chosen_byte_of_the_next_connection_only() {
        let p = Proxy::start(echo_server()).expect("proxy");
        p.start_capture();
        p.tamper_next(Tamper { dir: Direction::Down, at: 5, xor: 0xff });
        let mut s = client(&p);
        s.write_all(b"0123456789").expect("write");
        let mut got = [0u8; 10];
        s.read_exact(&mut got).expect("echo");
        assert_eq!(&got, b"01234\xca6789", "byte 5 of the way down");
        let mut s = client(&p);
        s.write_all(b"0123456789").expect("write");
        s.read_exact(&mut got).expect("echo");
        assert_eq!(&got, b"0123456789", "the next connection is left alone");
        let conns = p.captured_connections();
        assert_eq!(conns.len(), 2);
        assert_eq!(conns[0], [b"0123456789".to_vec(), b"01234\xca6789".to_vec()]);
    }

    #[test]
    fn cut_all_closes_open_connections_and_stall_holds_bytes() {
        let p = Proxy::start(echo_server()).expect("proxy");
        let mut s = client(&p);
        s.write_all(b"x").expect("write");
        let mut b = [0u8; 1];
        s.read_exact(&mut b).expect("echo");
        p.cut_all();
        assert!(read_all(&mut s).is_empty(), "bytes after the cut");

        p.set_mode(LinkMode::Stall);
        let mut s = client(&p);
        s.set_read_timeout(Some(Duration::from_millis(200))).expect("timeout");
        s.write_all(b"y").expect("write");
        let err = s.read(&mut b).expect_err("a stalled link answered");
        assert!(matches!(
            err.kind(),
            std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
        ));
        p.set_mode(LinkMode::Pass);
        s.set_read_timeout(Some(Duration::from_secs(5))).expect("timeout");
        s.read_exact(&mut b).expect("the stall ended");
        assert_eq!(&b, b"y");
    }
}
