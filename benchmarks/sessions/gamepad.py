"""A gamepad for the person sessions (``strol-bench interact --gamepad``), read through SDL's
game controllers (pygame's ``_sdl2.controller``: any pad SDL knows, in one layout), handed on
as ``keys.Pad`` (the W3C standard mapping the browser uses too)."""

from __future__ import annotations

from collections.abc import Callable

from strol_gym.benchmarks.sessions import keys

NO_GAMEPAD = (
    "--gamepad: no game controller found (SDL sees none; plug one in, or leave --gamepad out "
    "and use the keys)"
)


def first_gamepad() -> Callable[[], keys.Pad | None]:
    """The first game controller SDL finds, as a ``Pad`` reader (None once it is unplugged).
    ValueError when there is none or pygame cannot read controllers."""
    try:
        import pygame
        from pygame._sdl2 import controller
    except ImportError as e:  # pygame comes with highway-env; a build without SDL2's controller
        raise ValueError(f"--gamepad needs pygame with SDL2's game controller ({e})") from None
    pygame.display.init()  # SDL reads controllers when it pumps events: no window is opened
    controller.init()
    found = [i for i in range(controller.get_count()) if controller.is_controller(i)]
    if not found:
        raise ValueError(NO_GAMEPAD)
    pad = controller.Controller(found[0])
    axes = {name: getattr(pygame, f"CONTROLLER_AXIS_{name.upper()}") for name in _AXES}
    buttons = {
        name: getattr(pygame, f"CONTROLLER_BUTTON_{name.upper()}")
        for name in keys.SDL_BUTTONS.values()
    }

    def read() -> keys.Pad | None:
        pygame.event.pump()
        if not pad.attached():
            return None
        return keys.pad_from_sdl(
            {n: pad.get_axis(c) for n, c in axes.items()},
            {n: pad.get_button(c) for n, c in buttons.items()},
        )

    return read


_AXES = (*keys.SDL_AXES, *keys.SDL_TRIGGERS.values())


__all__ = ["NO_GAMEPAD", "first_gamepad"]
