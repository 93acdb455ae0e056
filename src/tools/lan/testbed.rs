//! A master host and N worker hosts as network namespaces around a bridge, every link
//! rate-limited by `tbf` in both directions; torn down when dropped.
//!
//! Names carry this process's id and a sequence number (`gridlight-PID-SEQ-ROLE`), so that
//! testbeds of parallel tests and of other processes never meet, and namespaces that a
//! killed process left behind (no destructor runs on SIGKILL) are recognised by their
//! dead owner's id and removed by the next build.

use std::net::Ipv4Addr;
use std::process::Command;
use std::sync::atomic::{AtomicU32, Ordering};

use serde::Serialize;

use super::ip::{ip, tc};
use super::LanError;

/// Prefix of every namespace a testbed makes.
const PREFIX: &str = "gridlight-";
/// The host side of every link (each host has its own namespace, so one name serves all).
pub const HOST_IFACE: &str = "eth0";
/// The testbed's subnet; the master is `.1`, worker host `i` is `.(10 + i)`.
const SUBNET: [u8; 3] = [10, 77, 0];
const MASTER_OCTET: u8 = 1;
const FIRST_WORKER_OCTET: u8 = 10;
/// Most worker hosts one testbed may have (addresses up to .250).
pub const MAX_WORKER_HOSTS: usize = 240;
/// How long a packet may wait in a token bucket before it is dropped.
const TBF_LATENCY: &str = "50ms";

static SEQUENCE: AtomicU32 = AtomicU32::new(0);

/// What to build.
#[derive(Clone, Copy, Debug)]
pub struct TestbedSpec {
    /// Worker hosts (the master's host comes in addition).
    pub worker_hosts: usize,
    /// Rate of every link, each direction, in Mbit/s.
    pub link_mbit: u32,
}

/// One host: its namespace and address.
#[derive(Clone, Debug)]
pub struct Host {
    /// `master` or `host-I`.
    pub name: String,
    pub namespace: String,
    pub address: Ipv4Addr,
    /// The switch's port for this host's link.
    port: String,
}

/// Bytes through a host's link, as its interface counts them (Ethernet frames).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct LinkCounters {
    /// Into the host.
    pub rx_bytes: u64,
    /// Out of the host.
    pub tx_bytes: u64,
}

/// A built testbed; dropping it removes every namespace (and so every link) it made.
#[derive(Debug)]
pub struct Testbed {
    spec: TestbedSpec,
    switch: String,
    hosts: Vec<Host>,
    /// Namespaces made so far, removed in reverse on drop.
    made: Vec<String>,
}

impl Testbed {
    /// Why a testbed cannot be built on this machine, or `None` when it can (checks root and
    /// iproute2, then makes and removes a probe namespace).
    pub fn unavailable() -> Option<LanError> {
        #[cfg(not(target_os = "linux"))]
        return Some(LanError::NotLinux);
        #[cfg(target_os = "linux")]
        {
            // SAFETY: geteuid has no preconditions.
            let uid = unsafe { libc::geteuid() };
            if uid != 0 {
                return Some(LanError::NotRoot(uid));
            }
            Self::probe()
        }
    }

    /// Makes and removes a probe namespace: whether `ip` and `tc` run and namespaces may
    /// be made here.
    #[cfg(target_os = "linux")]
    fn probe() -> Option<LanError> {
        let seq = SEQUENCE.fetch_add(1, Ordering::Relaxed);
        let probe = format!("{PREFIX}{}-{seq}-probe", std::process::id());
        let result = ip(&["netns", "add", &probe])
            .and_then(|_| tc(&["-V"]))
            .and_then(|_| ip(&["netns", "del", &probe]));
        let _ = ip(&["netns", "del", &probe]);
        result.err()
    }

    /// Builds the namespaces, the bridge and the rate-limited links.
    pub fn build(spec: TestbedSpec) -> Result<Self, LanError> {
        if spec.worker_hosts == 0 || spec.worker_hosts > MAX_WORKER_HOSTS {
            return Err(LanError::Spec(format!(
                "worker hosts must be 1 to {MAX_WORKER_HOSTS}, not {}",
                spec.worker_hosts
            )));
        }
        if spec.link_mbit == 0 {
            return Err(LanError::Spec("the link rate must be at least 1 Mbit/s".into()));
        }
        if cfg!(not(target_os = "linux")) {
            return Err(LanError::NotLinux);
        }
        remove_orphans();
        let seq = SEQUENCE.fetch_add(1, Ordering::Relaxed);
        let base = format!("{PREFIX}{}-{seq}", std::process::id());
        let host = |name: String, role: &str, octet: u8, port: String| Host {
            name,
            namespace: format!("{base}-{role}"),
            address: Ipv4Addr::new(SUBNET[0], SUBNET[1], SUBNET[2], octet),
            port,
        };
        let mut hosts = vec![host("master".into(), "m", MASTER_OCTET, "pm".into())];
        for i in 0..spec.worker_hosts {
            let octet = FIRST_WORKER_OCTET + i as u8;
            hosts.push(host(format!("host-{i}"), &format!("h{i}"), octet, format!("p{i}")));
        }
        // The guard exists before the first namespace, so any error below tears down.
        let mut bed = Testbed { spec, switch: format!("{base}-sw"), hosts, made: Vec::new() };
        bed.add_namespace(bed.switch.clone())?;
        ip(&["-n", &bed.switch, "link", "add", "br0", "type", "bridge"])?;
        ip(&["-n", &bed.switch, "link", "set", "br0", "up"])?;
        for host in bed.hosts.clone() {
            bed.add_namespace(host.namespace.clone())?;
            bed.add_link(&host)?;
        }
        Ok(bed)
    }

    /// The master's host.
    pub fn master(&self) -> &Host {
        &self.hosts[0]
    }

    /// The worker hosts.
    pub fn workers(&self) -> &[Host] {
        &self.hosts[1..]
    }

    /// Every host, the master's first.
    pub fn hosts(&self) -> &[Host] {
        &self.hosts
    }

    /// What was built.
    pub fn spec(&self) -> TestbedSpec {
        self.spec
    }

    /// Every namespace of the testbed (the switch's first).
    pub fn namespaces(&self) -> &[String] {
        &self.made
    }

    /// A link's rate in bytes per second, each direction.
    pub fn link_bytes_per_second(&self) -> f64 {
        f64::from(self.spec.link_mbit) * 1e6 / 8.0
    }

    /// The token bucket's depth: what a link may carry at once above its rate.
    pub fn burst_bytes(&self) -> u64 {
        // 10 ms at the link rate, at least 64 KiB so that a whole TSO segment fits.
        ((self.link_bytes_per_second() / 100.0) as u64).max(64 * 1024)
    }

    /// `program` to be run inside `host`'s namespace (`ip netns exec`).
    pub fn command(&self, host: &Host, program: impl AsRef<std::ffi::OsStr>) -> Command {
        let mut cmd = Command::new("ip");
        cmd.args(["netns", "exec", &host.namespace]).arg(program);
        cmd
    }

    /// The byte counters of `host`'s link.
    pub fn counters(&self, host: &Host) -> Result<LinkCounters, LanError> {
        let args = ["-n", host.namespace.as_str(), "-j", "-s", "link", "show", "dev", HOST_IFACE];
        let json = ip(&args)?;
        let bad = |why: String| LanError::Output { command: format!("ip {}", args.join(" ")), why };
        let value: serde_json::Value =
            serde_json::from_str(&json).map_err(|e| bad(format!("not JSON: {e}")))?;
        let stats = &value[0]["stats64"];
        let field = |dir: &str| {
            stats[dir]["bytes"].as_u64().ok_or_else(|| bad(format!("no stats64.{dir}.bytes")))
        };
        Ok(LinkCounters { rx_bytes: field("rx")?, tx_bytes: field("tx")? })
    }

    fn add_namespace(&mut self, name: String) -> Result<(), LanError> {
        ip(&["netns", "add", &name])?;
        self.made.push(name.clone());
        ip(&["-n", &name, "link", "set", "lo", "up"])?;
        Ok(())
    }

    /// A veth pair from `host` to the switch, addressed, up and rate-limited both ways.
    fn add_link(&self, host: &Host) -> Result<(), LanError> {
        let (ns, sw, port) = (host.namespace.as_str(), self.switch.as_str(), host.port.as_str());
        // Both ends are made inside their namespaces: none ever exists in the machine's.
        ip(&[
            "link", "add", HOST_IFACE, "netns", ns, "type", "veth", "peer", "name", port, "netns",
            sw,
        ])?;
        ip(&["-n", sw, "link", "set", port, "master", "br0"])?;
        ip(&["-n", sw, "link", "set", port, "up"])?;
        let cidr = format!("{}/24", host.address);
        ip(&["-n", ns, "addr", "add", &cidr, "dev", HOST_IFACE])?;
        ip(&["-n", ns, "link", "set", HOST_IFACE, "up"])?;
        self.limit(ns, HOST_IFACE)?;
        self.limit(sw, port)
    }

    /// A token bucket on `dev`'s egress in namespace `ns`.
    fn limit(&self, ns: &str, dev: &str) -> Result<(), LanError> {
        let rate = format!("{}mbit", self.spec.link_mbit);
        let burst = self.burst_bytes().to_string();
        // `latency` bounds the queue: a packet waits at most this long for tokens.
        let (rate, burst) = (rate.as_str(), burst.as_str());
        let qdisc = ["qdisc", "add", "dev", dev, "root", "tbf", "rate", rate, "burst", burst];
        tc(&[&["-n", ns][..], &qdisc, &["latency", TBF_LATENCY]].concat())?;
        Ok(())
    }
}

impl Drop for Testbed {
    fn drop(&mut self) {
        // Hosts before the switch; deleting a namespace deletes its veth ends and their peers.
        for name in self.made.drain(..).rev() {
            if let Err(err) = ip(&["netns", "del", &name]) {
                tracing::warn!(namespace = %name, cause = %err, "cannot remove a testbed namespace");
            }
        }
    }
}

/// Removes testbed namespaces whose owning process no longer exists (there are none off
/// Linux).
#[cfg(not(target_os = "linux"))]
fn remove_orphans() {}

/// Removes testbed namespaces whose owning process no longer exists.
#[cfg(target_os = "linux")]
fn remove_orphans() {
    let Ok(list) = ip(&["netns", "list"]) else { return };
    for name in list.lines().filter_map(|l| l.split_whitespace().next()) {
        let Some(pid) = name.strip_prefix(PREFIX).and_then(|r| r.split('-').next()) else {
            continue;
        };
        let Ok(pid) = pid.parse::<i32>() else { continue };
        // SAFETY: signal 0 only checks that the process exists.
        let alive = unsafe { libc::kill(pid, 0) } == 0
            || std::io::Error::last_os_error().raw_os_error() == Some(libc::EPERM);
        if !alive {
            let _ = ip(&["netns", "del", name]);
        }
    }
}
