//! The viewer's per-frame logic, free of any window: a fly camera driven by keys and mouse,
//! the actions keys trigger, and when accumulation must restart. Tested without a window.
use glam::Vec3;
use kernels::camera::look_at;
use kernels::types::{Camera, RESTIR_TEMPORAL, RESTIR_UNBIASED};

use crate::integrator::Integrator;
use crate::options::MAX_SPATIAL_PASSES;

/// Keys the viewer understands (mapped from the windowing library's key codes).
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Key {
    W,
    A,
    S,
    D,
    Q,
    E,
    R,
    P,
    T,
    B,
    Digit(u8),
    PlusSpatial,
    MinusSpatial,
    /// `[` and `]`: turn the environment map about the up axis.
    TurnEnvLeft,
    TurnEnvRight,
    Escape,
}

/// How far one press of `[` or `]` turns the environment.
pub const ENV_TURN_DEGREES: f32 = 15.0;

/// What a key press asks for.
#[derive(Copy, Clone, Debug, PartialEq)]
pub enum Action {
    SetIntegrator(Integrator),
    ToggleTemporal,
    ToggleUnbiased,
    SpatialPasses(i32),
    /// Turn the environment by this many degrees about the up axis.
    TurnEnvironment(f32),
    ResetCamera,
    Save,
    Quit,
}

pub fn action_for(key: Key) -> Option<Action> {
    match key {
        // 1 ao, 2 pt, 3 nee, 4 mis, 5 ris, 6 restir
        Key::Digit(d) if (1..=Integrator::ALL.len() as u32).contains(&(d as u32)) => {
            Some(Action::SetIntegrator(Integrator::ALL[d as usize - 1]))
        }
        Key::T => Some(Action::ToggleTemporal),
        Key::B => Some(Action::ToggleUnbiased),
        Key::PlusSpatial => Some(Action::SpatialPasses(1)),
        Key::MinusSpatial => Some(Action::SpatialPasses(-1)),
        Key::TurnEnvLeft => Some(Action::TurnEnvironment(-ENV_TURN_DEGREES)),
        Key::TurnEnvRight => Some(Action::TurnEnvironment(ENV_TURN_DEGREES)),
        Key::R => Some(Action::ResetCamera),
        Key::P => Some(Action::Save),
        Key::Escape => Some(Action::Quit),
        _ => None,
    }
}

/// Movement keys held down.
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct Held {
    pub forward: bool,
    pub back: bool,
    pub left: bool,
    pub right: bool,
    pub up: bool,
    pub down: bool,
}

impl Held {
    /// Track a movement key; returns false for keys that do not move.
    pub fn set(&mut self, key: Key, down: bool) -> bool {
        let slot = match key {
            Key::W => &mut self.forward,
            Key::S => &mut self.back,
            Key::A => &mut self.left,
            Key::D => &mut self.right,
            Key::E => &mut self.up,
            Key::Q => &mut self.down,
            _ => return false,
        };
        *slot = down;
        true
    }
}

/// A camera that flies: position, yaw and pitch about the world's up axis.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct FlyCamera {
    pub position: Vec3,
    pub yaw: f32,
    pub pitch: f32,
    pub up: Vec3,
    pub fov: f32,
    /// Units per second.
    pub speed: f32,
    home: (Vec3, f32, f32, f32),
}

/// Radians of turn per pixel of mouse drag.
const LOOK_SENSITIVITY: f32 = 0.004;

impl FlyCamera {
    pub fn new(eye: Vec3, target: Vec3, up: Vec3, fov: f32, scene_extent: f32) -> Self {
        let up = up.normalize();
        let d = (target - eye).normalize();
        // Yaw about `up` in the plane orthogonal to it; pitch towards `up`.
        let (right0, fwd0) = Self::basis(up);
        let pitch = d.dot(up).clamp(-1.0, 1.0).asin();
        let flat = d - up * d.dot(up);
        let yaw = flat.dot(right0).atan2(flat.dot(fwd0));
        let speed = (0.25 * scene_extent).max(1e-3);
        Self {
            position: eye,
            yaw,
            pitch,
            up,
            fov,
            speed,
            home: (eye, yaw, pitch, speed),
        }
    }

    /// A reference forward and right direction orthogonal to `up`.
    fn basis(up: Vec3) -> (Vec3, Vec3) {
        let helper = if up.z.abs() < 0.9 { Vec3::Z } else { Vec3::X };
        let fwd0 = (helper - up * helper.dot(up)).normalize();
        let right0 = fwd0.cross(up);
        (right0, fwd0)
    }

    pub fn forward(&self) -> Vec3 {
        let (right0, fwd0) = Self::basis(self.up);
        let flat = fwd0 * self.yaw.cos() + right0 * self.yaw.sin();
        (flat * self.pitch.cos() + self.up * self.pitch.sin()).normalize()
    }

    pub fn camera(&self, aspect: f32) -> Camera {
        look_at(
            self.position,
            self.position + self.forward(),
            self.up,
            self.fov,
            aspect,
        )
    }

    /// Move for `dt` seconds with the held keys; true when the camera moved.
    pub fn fly(&mut self, held: &Held, dt: f32) -> bool {
        let f = self.forward();
        let r = f.cross(self.up).normalize();
        let axis = |a: bool, b: bool| (a as i32 - b as i32) as f32;
        let v = f * axis(held.forward, held.back)
            + r * axis(held.right, held.left)
            + self.up * axis(held.up, held.down);
        if v == Vec3::ZERO || dt <= 0.0 {
            return false;
        }
        self.position += v.normalize() * self.speed * dt;
        true
    }

    /// Turn by a mouse drag of (dx, dy) pixels; true when the camera turned.
    pub fn look(&mut self, dx: f32, dy: f32) -> bool {
        if dx == 0.0 && dy == 0.0 {
            return false;
        }
        self.yaw += dx * LOOK_SENSITIVITY;
        self.pitch = (self.pitch - dy * LOOK_SENSITIVITY).clamp(-1.55, 1.55);
        true
    }

    /// Scroll wheel: each notch changes the speed by 20%.
    pub fn scroll(&mut self, notches: f32) {
        self.speed *= 1.2f32.powf(notches);
    }

    pub fn reset(&mut self) {
        (self.position, self.yaw, self.pitch, self.speed) = self.home;
    }
}

/// What the viewer shows and how: integrator, ReSTIR switches, and progressive
/// accumulation that restarts whenever the picture would change.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewState {
    pub integrator: Integrator,
    pub restir_flags: u32,
    pub spatial_passes: u32,
    /// Degrees the environment is turned beyond `--env-rotate`.
    pub env_turn: f32,
    /// Frames accumulated since the last restart.
    pub accumulated: u32,
    /// Frames rendered in all: the ReSTIR frame index, never reset, so that frames of a
    /// moving camera draw new random numbers.
    pub frame: u32,
    /// Whether the last frame left ReSTIR reservoirs that this frame may reuse: not after a
    /// switch of integrator or of weighting (reservoirs weighted the other way are no history).
    pub restir_history: bool,
    pub quit: bool,
    pub save_requested: bool,
}

impl ViewState {
    pub fn new(integrator: Integrator, restir_flags: u32, spatial_passes: u32) -> Self {
        Self {
            integrator,
            restir_flags,
            spatial_passes,
            env_turn: 0.0,
            accumulated: 0,
            frame: 0,
            restir_history: false,
            quit: false,
            save_requested: false,
        }
    }

    /// Apply an action; returns true when accumulation must restart.
    pub fn apply(&mut self, action: Action, camera: &mut FlyCamera) -> bool {
        match action {
            Action::SetIntegrator(i) => {
                let changed = i != self.integrator;
                self.integrator = i;
                self.restir_history &= !changed;
                changed
            }
            Action::ToggleTemporal => {
                self.restir_flags ^= RESTIR_TEMPORAL;
                true
            }
            Action::ToggleUnbiased => {
                self.restir_flags ^= RESTIR_UNBIASED;
                self.restir_history = false;
                true
            }
            Action::SpatialPasses(d) => {
                self.spatial_passes =
                    (self.spatial_passes as i32 + d).clamp(0, MAX_SPATIAL_PASSES as i32) as u32;
                true
            }
            Action::TurnEnvironment(degrees) => {
                self.env_turn = (self.env_turn + degrees).rem_euclid(360.0);
                // The light moved: the reservoirs' samples no longer mean what they did.
                self.restir_history = false;
                true
            }
            Action::ResetCamera => {
                camera.reset();
                true
            }
            Action::Save => {
                self.save_requested = true;
                false
            }
            Action::Quit => {
                self.quit = true;
                false
            }
        }
    }

    /// A frame was rendered; `restart` says whether it started a new accumulation.
    pub fn frame_done(&mut self, restart: bool) {
        self.accumulated = if restart { 1 } else { self.accumulated + 1 };
        self.frame += 1;
        self.restir_history = self.integrator == Integrator::Restir;
    }

    pub fn title(&self, width: u32, height: u32, gpu_ms: f64) -> String {
        let restir = if self.integrator == Integrator::Restir {
            format!(
                " [temporal {}, spatial x{}, {}]",
                if self.restir_flags & RESTIR_TEMPORAL != 0 {
                    "on"
                } else {
                    "off"
                },
                self.spatial_passes,
                if self.restir_flags & RESTIR_UNBIASED != 0 {
                    "unbiased"
                } else {
                    "biased"
                }
            )
        } else {
            String::new()
        };
        format!(
            "runner view: {:?}{restir} {width}x{height} {gpu_ms:.2} ms/frame (GPU) {} frames",
            self.integrator, self.accumulated
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam() -> FlyCamera {
        FlyCamera::new(
            Vec3::new(0.0, 1.0, 5.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::Y,
            45.0,
            10.0,
        )
    }

    #[test]
    fn starts_looking_at_the_target() {
        let c = cam();
        assert!(
            (c.forward() - Vec3::new(0.0, 0.0, -1.0)).length() < 1e-5,
            "{}",
            c.forward()
        );
        let tilted = FlyCamera::new(Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::Y, 45.0, 1.0);
        assert!((tilted.forward() - Vec3::new(1.0, 1.0, 0.0).normalize()).length() < 1e-5);
    }

    #[test]
    fn wasd_moves_along_view_axes_at_speed() {
        let mut c = cam();
        let mut held = Held::default();
        assert!(!c.fly(&held, 0.1), "no key, no motion");
        held.set(Key::W, true);
        assert!(c.fly(&held, 0.5));
        assert!(
            (c.position - Vec3::new(0.0, 1.0, 5.0 - 0.5 * 2.5)).length() < 1e-5,
            "{}",
            c.position
        );
        held.set(Key::W, false);
        held.set(Key::D, true);
        let before = c.position;
        c.fly(&held, 1.0);
        assert!(
            (c.position - before - Vec3::new(2.5, 0.0, 0.0)).length() < 1e-4,
            "right is +x"
        );
        held = Held::default();
        held.set(Key::E, true);
        let before = c.position;
        c.fly(&held, 1.0);
        assert!(
            (c.position - before - Vec3::new(0.0, 2.5, 0.0)).length() < 1e-4,
            "E is up"
        );
    }

    #[test]
    fn mouse_turns_scroll_scales_and_r_resets() {
        let mut c = cam();
        let home = c;
        assert!(c.look(100.0, 0.0));
        assert!(
            c.forward().x > 0.3,
            "drag right turns right: {}",
            c.forward()
        );
        c.look(0.0, -10_000.0);
        assert!(c.pitch <= 1.55, "pitch is clamped");
        c.scroll(1.0);
        assert!((c.speed - home.speed * 1.2).abs() < 1e-5);
        let mut s = ViewState::new(Integrator::Nee, 0, 1);
        assert!(s.apply(action_for(Key::R).unwrap(), &mut c));
        assert_eq!(c, home);
    }

    #[test]
    fn integrator_switches_and_accumulation_restarts() {
        let mut c = cam();
        let mut s = ViewState::new(Integrator::Nee, RESTIR_TEMPORAL, 1);
        s.frame_done(true);
        s.frame_done(false);
        s.frame_done(false);
        assert_eq!((s.accumulated, s.frame), (3, 3));
        assert!(
            !s.apply(action_for(Key::Digit(3)).unwrap(), &mut c),
            "same integrator: keep accumulating"
        );
        assert!(s.apply(action_for(Key::Digit(6)).unwrap(), &mut c));
        assert_eq!(s.integrator, Integrator::Restir);
        assert!(s.apply(action_for(Key::T).unwrap(), &mut c));
        assert_eq!(s.restir_flags & RESTIR_TEMPORAL, 0);
        assert!(s.apply(action_for(Key::B).unwrap(), &mut c));
        assert_ne!(s.restir_flags & RESTIR_UNBIASED, 0);
        assert!(
            s.title(64, 32, 1.5).contains("temporal off")
                && s.title(64, 32, 1.5).contains("unbiased")
        );
        assert!(!s.apply(action_for(Key::P).unwrap(), &mut c) && s.save_requested);
        // Turning the environment restarts and drops ReSTIR's history; 24 turns come round.
        s.frame_done(false);
        assert!(s.restir_history);
        assert!(s.apply(action_for(Key::TurnEnvRight).unwrap(), &mut c));
        assert!(!s.restir_history && s.env_turn == ENV_TURN_DEGREES);
        for _ in 0..24 {
            s.apply(action_for(Key::TurnEnvLeft).unwrap(), &mut c);
        }
        assert!(
            (s.env_turn - ENV_TURN_DEGREES).abs() < 1e-3,
            "{}",
            s.env_turn
        );
        s.frame_done(true);
        assert_eq!(s.accumulated, 1);
        assert_eq!(action_for(Key::Digit(9)), None);
        assert_eq!(
            action_for(Key::W),
            None,
            "movement keys are held, not actions"
        );
    }

    /// ReSTIR reuses the last frame's reservoirs only if that frame was a ReSTIR frame with
    /// the same weighting; the frame index keeps counting through restarts.
    #[test]
    fn restir_history_is_dropped_when_integrator_or_weighting_changes() {
        let mut c = cam();
        let mut s = ViewState::new(Integrator::Restir, RESTIR_TEMPORAL, 1);
        assert!(!s.restir_history, "no history before the first frame");
        s.frame_done(true);
        assert!(s.restir_history);
        s.frame_done(true); // a camera move restarts the accumulation, not the history
        assert!(s.restir_history && s.frame == 2 && s.accumulated == 1);
        s.apply(action_for(Key::B).unwrap(), &mut c);
        assert!(
            !s.restir_history,
            "biased and unbiased reservoirs are weighted differently"
        );
        s.frame_done(true);
        s.apply(action_for(Key::Digit(3)).unwrap(), &mut c);
        assert!(!s.restir_history);
        s.frame_done(true);
        s.apply(action_for(Key::Digit(6)).unwrap(), &mut c);
        assert!(!s.restir_history, "the frame before was not a ReSTIR frame");
        s.frame_done(true);
        assert!(s.restir_history && s.frame == 5);
    }
}

#[cfg(test)]
mod camera_roundtrip {
    use super::*;
    #[test]
    fn fly_camera_reproduces_the_look_at_camera() {
        for (eye, target, up) in [
            (
                Vec3::new(278.0, 273.0, -800.0),
                Vec3::new(278.0, 273.0, 0.0),
                Vec3::Y,
            ),
            (
                Vec3::new(0.0, 4.0, 24.0),
                Vec3::new(0.0, 0.5, -2.0),
                Vec3::Y,
            ),
            (Vec3::new(1.0, 2.0, 3.0), Vec3::new(-2.0, 0.0, 1.0), Vec3::Z),
        ] {
            let want = look_at(eye, target, up, 39.3, 4.0 / 3.0);
            let got = FlyCamera::new(eye, target, up, 39.3, 100.0).camera(4.0 / 3.0);
            for (a, b) in [
                (want.forward, got.forward),
                (want.right, got.right),
                (want.up, got.up),
            ] {
                assert!(
                    (Vec3::from(a) - Vec3::from(b)).length() < 1e-5,
                    "{a:?} vs {b:?}"
                );
            }
        }
    }
}
