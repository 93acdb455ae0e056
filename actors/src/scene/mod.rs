//! Scene values: the absolute, versioned [`state::SceneState`] a worker renders, the
//! edits that change it ([`edit`], timed in a [`script`]), and the assets it names
//! ([`asset_store`]). Plain data, no actor.

pub mod asset_store;
pub mod edit;
pub mod script;
pub mod state;
