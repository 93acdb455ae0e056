//! `--when-idle`'s keyboard/mouse source against a real X server (Xvfb): the screen-saver
//! extension's idle time is read, and grows while nobody touches the display. Without
//! `Xvfb` on the machine the test says it is skipped and why (`.ci/run` installs it).

use std::time::Duration;

use gridlight::worker::idle::input::{InputIdle, InputSource, X11};

mod support;
use support::xvfb::Xvfb;

fn known(i: InputIdle) -> Duration {
    match i {
        InputIdle::Known(d) => d,
        InputIdle::Unknown => panic!("the X server's idle time is unknown"),
    }
}

#[test]
fn the_x_servers_idle_time_is_read_and_grows_without_input() {
    let Some(xvfb) =
        Xvfb::start_or_skip("the_x_servers_idle_time_is_read_and_grows_without_input", 320, 240)
    else {
        return;
    };
    let mut x = X11::connect_to(Some(&xvfb.display)).expect("Xvfb has MIT-SCREEN-SAVER");
    let first = known(x.idle());
    std::thread::sleep(Duration::from_millis(600));
    let second = known(x.idle());
    assert!(second >= first + Duration::from_millis(400), "{first:?} then {second:?}");
    drop(xvfb);
    // The server is gone: unknown, never "idle".
    std::thread::sleep(Duration::from_millis(200));
    assert_eq!(x.idle(), InputIdle::Unknown);
}

#[test]
fn no_x_server_is_an_error_not_an_idle_desk() {
    assert!(X11::connect_to(Some(":999")).is_err());
}
