//! The handshake: `Hello` (protocol version, name), the HMAC challenge and `Auth`, then
//! `Welcome` with the set layout and the asset manifest.

use super::{Action, Phase, ProtocolState};
use crate::wire::auth;
use crate::wire::integrity::ResultKey;
use crate::wire::protocol::{MasterMsg, PROTOCOL_VERSION};
use crate::wire::rejection::Rejection;

/// Longest worker name accepted.
pub const MAX_NAME_LEN: usize = 256;

impl ProtocolState {
    /// `Hello`: the worker's name and cores noted, its protocol version checked, and the
    /// challenge sent.
    pub(super) fn on_hello(
        &mut self,
        protocol: u32,
        name: &str,
        cores: u32,
        out: &mut Vec<Action>,
    ) -> Result<(), Rejection> {
        self.name = sanitize(name);
        self.cores = cores;
        if protocol != PROTOCOL_VERSION {
            return Err(Rejection::Version { worker: protocol, master: PROTOCOL_VERSION });
        }
        if name.is_empty() || name.len() > MAX_NAME_LEN {
            return Err(Rejection::Name { max: MAX_NAME_LEN });
        }
        let nonce = auth::nonce();
        self.phase = Phase::Auth { nonce };
        let auth_required = self.config.secret.is_some();
        out.push(Action::Send(MasterMsg::Challenge { nonce, auth_required }));
        Ok(())
    }

    /// `Auth`: the MAC checked against the challenge's `nonce` when a secret is set; the
    /// worker is welcomed and its results' key derived.
    pub(super) fn on_auth(
        &mut self,
        nonce: [u8; 32],
        mac: Option<[u8; 32]>,
        out: &mut Vec<Action>,
    ) -> Result<(), Rejection> {
        if let Some(secret) = &self.config.secret {
            match mac {
                None => return Err(Rejection::NoSecret),
                Some(m) if !auth::verify(secret, &nonce, &m) => return Err(Rejection::WrongSecret),
                Some(_) => {}
            }
        }
        let key = ResultKey::derive(self.config.secret.as_deref(), &nonce);
        self.phase = Phase::Work { key };
        self.welcomed = true;
        out.push(Action::Joined);
        out.push(Action::Send(MasterMsg::Welcome {
            worker_id: self.id,
            sets: self.config.sets.config(),
            assets: self.config.assets.manifest().to_vec(),
        }));
        Ok(())
    }
}

/// A name safe to put in logs (no control characters).
fn sanitize(name: &str) -> String {
    name.chars().take(MAX_NAME_LEN).map(|c| if c.is_control() { '?' } else { c }).collect()
}
