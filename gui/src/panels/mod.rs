//! The window's panels, one module each: the read-out and machine buttons ([`dro`]), jog
//! and program ([`controls`]), and the tabs ([`path`], [`plots`], [`scope`],
//! [`settings`], [`identify`], [`tune`]). Each draws from the app's state and acts only by sending
//! commands to the session.

pub mod controls;
pub mod dro;
pub mod identify;
pub mod path;
pub mod plots;
pub mod scope;
pub mod settings;
pub mod tune;
