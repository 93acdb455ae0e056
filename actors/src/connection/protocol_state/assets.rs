//! Serving manifest assets: every chunk of a listed asset, in order, in answer to one
//! `AssetRequest`.

use super::{Action, ProtocolState};
use crate::wire::protocol::{AssetHash, MasterMsg, ASSET_CHUNK_LEN};
use crate::wire::rejection::Rejection;

impl ProtocolState {
    /// Every chunk of a manifest asset.
    pub(super) fn serve_asset(
        &self,
        hash: AssetHash,
        out: &mut Vec<Action>,
    ) -> Result<(), Rejection> {
        let assets = &self.config.assets;
        let not_listed = || Rejection::NotInManifest { hash: hex(&hash) };
        let entry = assets.entry(&hash).ok_or_else(not_listed)?;
        let mut offset = 0u64;
        loop {
            let chunk = match assets.read_chunk(&hash, offset, ASSET_CHUNK_LEN) {
                Some(Ok(c)) => c,
                Some(Err(e)) => {
                    let (path, cause) = (entry.path.clone(), e.to_string());
                    return Err(Rejection::AssetUnreadable { path, cause });
                }
                None => return Err(not_listed()),
            };
            let n = chunk.len() as u64;
            out.push(Action::Send(MasterMsg::AssetChunk {
                hash,
                offset,
                len: entry.len,
                data: chunk,
            }));
            offset += n;
            if offset >= entry.len || n == 0 {
                return Ok(());
            }
        }
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}
