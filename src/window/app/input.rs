//! The window's input: mouse gestures (orbit, pan, pick, drag), keys (flying, nudges,
//! shortcuts) and where a window position lies in the picture.

// The application's imports and types (a split of one file, not a separate concern).
use super::*;

/// Pixels the mouse may move between press and release and still count as a click.
const CLICK_SLOP: f32 = 4.0;

/// Fraction of the camera's distance to its target that one nudge key moves an object.
const NUDGE_FRACTION: f32 = 0.02;

/// The mouse gesture in progress.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Gesture {
    None,
    /// Button down, not yet far enough to be a drag: a click on release.
    Pressed {
        at: Vec2,
        button: MouseButton,
    },
    /// Dragging the camera.
    Camera {
        last: Vec2,
    },
    /// Dragging the selected object.
    Object {
        object: u32,
        last: Vec2,
    },
}

impl App {
    /// The render pixel under window position `p`, if the picture is there.
    pub(super) fn picture_pixel(&self, p: Vec2) -> Option<Vec2> {
        let res = self.scene.resolution;
        layout::window_to_picture(self.picture_rect?, res.width, res.height, p)
    }

    /// Scale from window pixels to render pixels.
    pub(super) fn picture_scale(&self) -> f32 {
        match self.picture_rect {
            Some(r) if r.height > 0.0 => self.scene.resolution.height as f32 / r.height,
            _ => 1.0,
        }
    }

    pub(super) fn on_press(&mut self, button: MouseButton) {
        if self.picture_pixel(self.cursor).is_some() {
            self.gesture = Gesture::Pressed { at: self.cursor, button };
        }
    }

    pub(super) fn on_release(&mut self) {
        if let Gesture::Pressed { at, button: MouseButton::Left } = self.gesture {
            // A click: pick what is under the mouse (the shown frame's scene).
            if let Some(px) = self.picture_pixel(at) {
                self.selected = self.master.pick(px.x, px.y);
                self.message = match self.selected.and_then(|i| self.scene.objects.get(i as usize))
                {
                    Some(o) => format!("selected {}", o.name),
                    None => "nothing there to select".into(),
                };
            }
        }
        self.gesture = Gesture::None;
    }

    pub(super) fn on_cursor(&mut self, p: Vec2) {
        self.cursor = p;
        match self.gesture {
            Gesture::Pressed { at, button } if (p - at).length() > CLICK_SLOP => {
                // Dragging with the left button from the selected object moves it.
                let over_selected = button == MouseButton::Left
                    && self.selected.is_some()
                    && self.picture_pixel(at).and_then(|px| self.master.pick(px.x, px.y))
                        == self.selected;
                self.gesture = match (over_selected, self.selected) {
                    (true, Some(object)) => Gesture::Object { object, last: at },
                    _ => Gesture::Camera { last: at },
                };
                self.on_cursor(p);
            }
            Gesture::Camera { last } => {
                let d = p - last;
                let camera = self.controller.drag(&self.scene.camera, d.x, d.y);
                self.edit(WindowEdit::Camera(camera));
                self.gesture = Gesture::Camera { last: p };
            }
            Gesture::Object { object, last } => {
                let d = (p - last) * self.picture_scale();
                if let Some(o) = self.scene.objects.get(object as usize) {
                    let offset = manipulate::drag_offset(
                        &self.scene.camera,
                        o.transform.translation,
                        d.x,
                        d.y,
                        self.scene.resolution.height,
                    );
                    let transform = manipulate::moved(o.transform, offset);
                    self.edit(WindowEdit::ObjectTransform { object, transform });
                }
                self.gesture = Gesture::Object { object, last: p };
            }
            _ => {}
        }
    }

    pub(super) fn on_key(&mut self, code: KeyCode, pressed: bool) {
        let keys = &mut self.keys;
        match code {
            KeyCode::KeyW => keys.forward = pressed,
            KeyCode::KeyS => keys.back = pressed,
            KeyCode::KeyA => keys.left = pressed,
            KeyCode::KeyD => keys.right = pressed,
            KeyCode::KeyE => keys.up = pressed,
            KeyCode::KeyQ => keys.down = pressed,
            _ if !pressed => {}
            KeyCode::KeyR => self.edit(WindowEdit::Camera(self.controller.reset())),
            KeyCode::F12 | KeyCode::KeyP => self.screenshot(),
            KeyCode::Escape => self.selected = None,
            KeyCode::Digit1
            | KeyCode::Digit2
            | KeyCode::Digit3
            | KeyCode::Digit4
            | KeyCode::Digit5
            | KeyCode::Digit6 => {
                let i = match code {
                    KeyCode::Digit1 => 0,
                    KeyCode::Digit2 => 1,
                    KeyCode::Digit3 => 2,
                    KeyCode::Digit4 => 3,
                    KeyCode::Digit5 => 4,
                    _ => 5,
                };
                self.settings.view = crate::master::view::View::ALL[i];
            }
            KeyCode::ArrowLeft => self.nudge(Nudge::Left),
            KeyCode::ArrowRight => self.nudge(Nudge::Right),
            KeyCode::ArrowUp => self.nudge(Nudge::Away),
            KeyCode::ArrowDown => self.nudge(Nudge::Towards),
            KeyCode::PageUp => self.nudge(Nudge::Up),
            KeyCode::PageDown => self.nudge(Nudge::Down),
            _ => {}
        }
        self.last_move = Instant::now();
    }

    pub(super) fn nudge(&mut self, nudge: Nudge) {
        let Some(object) = self.selected else { return };
        let Some(o) = self.scene.objects.get(object as usize) else { return };
        let cam = &self.scene.camera;
        let step = (cam.look_at - cam.position).length() * NUDGE_FRACTION;
        let transform = manipulate::moved(o.transform, manipulate::nudge_offset(cam, nudge, step));
        self.edit(WindowEdit::ObjectTransform { object, transform });
    }

    /// Fly movement for the time since the last step, while movement keys are held.
    pub(super) fn fly_step(&mut self) {
        let now = Instant::now();
        let dt = now.duration_since(self.last_move).as_secs_f32().min(0.1);
        self.last_move = now;
        if self.keys.any() {
            let camera = self.controller.fly(&self.scene.camera, self.keys, dt);
            self.edit(WindowEdit::Camera(camera));
        }
    }
}
