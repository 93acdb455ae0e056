//! Fault injection for the supervision tests: a [`PanicPlan`] makes the guard panic at a
//! chosen actor and [`Site`], so that a real master (`gridlight master --inject-panic
//! ACTOR[:SITE[:COUNT]]`, a hidden test hook) can be driven into a restart or past its
//! restart intensity. The guard asks the plan before every body it runs; an empty plan
//! costs one branch.

use std::str::FromStr;
use std::sync::Mutex;

use thiserror::Error;

use super::{ActorKind, Site};

/// Panic in `actor` at `site`, `count` times (`None`: every time).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PanicInjection {
    pub actor: ActorKind,
    pub site: Site,
    pub count: Option<u32>,
}

/// A `--inject-panic` value that does not parse.
#[derive(Debug, Error, PartialEq, Eq)]
pub enum InjectionError {
    #[error("unknown actor `{0}` (one of: {list})", list = ActorKind::NAMES.join(", "))]
    Actor(String),
    #[error("unknown site `{0}` (one of: started, handler, timer)")]
    Site(String),
    #[error("bad count `{0}`: a whole number of panics, at least 1")]
    Count(String),
    #[error("`{0}` has more than ACTOR:SITE:COUNT")]
    TooLong(String),
}

impl FromStr for PanicInjection {
    type Err = InjectionError;

    /// `ACTOR[:SITE[:COUNT]]`; the site defaults to `started`, the count to unlimited.
    fn from_str(s: &str) -> Result<Self, InjectionError> {
        let mut parts = s.split(':');
        let actor = parts.next().unwrap_or_default();
        let actor =
            ActorKind::from_name(actor).ok_or_else(|| InjectionError::Actor(actor.into()))?;
        let site = match parts.next() {
            None => Site::Started,
            Some(site) => Site::from_name(site).ok_or_else(|| InjectionError::Site(site.into()))?,
        };
        let count = match parts.next() {
            None => None,
            Some(n) => match n.parse::<u32>() {
                Ok(n) if n > 0 => Some(n),
                _ => return Err(InjectionError::Count(n.into())),
            },
        };
        if parts.next().is_some() {
            return Err(InjectionError::TooLong(s.into()));
        }
        Ok(Self { actor, site, count })
    }
}

/// The injections of one master run, consumed as they fire.
#[derive(Debug, Default)]
pub struct PanicPlan {
    /// Empty in every run but the tests' (checked without the lock).
    armed: bool,
    left: Mutex<Vec<PanicInjection>>,
}

impl PanicPlan {
    pub fn new(injections: &[PanicInjection]) -> Self {
        Self { armed: !injections.is_empty(), left: Mutex::new(injections.to_vec()) }
    }

    /// Whether any injection was configured (the guard skips the plan otherwise).
    pub fn armed(&self) -> bool {
        self.armed
    }

    /// Panics when an injection for `actor` at `site` has panics left.
    pub fn fire(&self, actor: ActorKind, site: Site) {
        if !self.armed || !self.take(actor, site) {
            return;
        }
        panic!("injected panic in the {actor}'s {site}");
    }

    /// Uses up one panic of a matching injection; whether there was one.
    fn take(&self, actor: ActorKind, site: Site) -> bool {
        let mut left = self.left.lock().unwrap_or_else(|p| p.into_inner());
        let Some(i) = left.iter().position(|j| j.actor == actor && j.site == site) else {
            return false;
        };
        match &mut left[i].count {
            None => {}
            Some(1) => {
                left.remove(i);
            }
            Some(n) => *n -= 1,
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::supervision::contain;

    #[test]
    fn parses_actor_site_and_count_with_defaults() {
        let p: PanicInjection = "scheduler".parse().expect("actor only");
        assert_eq!(
            p,
            PanicInjection { actor: ActorKind::Scheduler, site: Site::Started, count: None }
        );
        let p: PanicInjection = "scene-holder:timer:3".parse().expect("all three");
        assert_eq!(
            p,
            PanicInjection { actor: ActorKind::SceneHolder, site: Site::Timer, count: Some(3) }
        );
        assert_eq!(
            "painter".parse::<PanicInjection>(),
            Err(InjectionError::Actor("painter".into()))
        );
        assert_eq!(
            "listener:loop".parse::<PanicInjection>(),
            Err(InjectionError::Site("loop".into()))
        );
        assert_eq!(
            "listener:handler:0".parse::<PanicInjection>(),
            Err(InjectionError::Count("0".into()))
        );
        assert!(matches!("a:b:1:2".parse::<PanicInjection>(), Err(InjectionError::Actor(_))));
        assert!(matches!(
            "presenter:timer:1:2".parse::<PanicInjection>(),
            Err(InjectionError::TooLong(_))
        ));
    }

    #[test]
    fn a_counted_injection_fires_that_many_times_at_its_site_only() {
        let plan = PanicPlan::new(&[PanicInjection {
            actor: ActorKind::Presenter,
            site: Site::Timer,
            count: Some(2),
        }]);
        assert!(contain(|| plan.fire(ActorKind::Presenter, Site::Handler)).is_ok());
        assert!(contain(|| plan.fire(ActorKind::Scheduler, Site::Timer)).is_ok());
        let first = contain(|| plan.fire(ActorKind::Presenter, Site::Timer));
        assert_eq!(first, Err("injected panic in the presenter's timer".to_owned()));
        assert!(contain(|| plan.fire(ActorKind::Presenter, Site::Timer)).is_err());
        assert!(contain(|| plan.fire(ActorKind::Presenter, Site::Timer)).is_ok(), "used up");
    }
}
