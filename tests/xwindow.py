"""Test helpers for real X windows on Xvfb: a screenshot, and closing a window the way a
window manager does (a WM_DELETE_WINDOW client message, which GLFW turns into "should
close"; `xdotool windowclose` destroys the window under the program instead)."""

from __future__ import annotations

import ctypes
import ctypes.util
import subprocess
import time


def xdotool(env: dict, *args: str, check: bool = True) -> str:
    """Run xdotool on the display of `env`; its output (a failure raises unless `check` is False)."""
    return subprocess.run(["xdotool", *args], env=env, capture_output=True, text=True, timeout=30, check=check).stdout


def find_window(env: dict, name: str = "MuJoCo", timeout: float = 120.0, process=None) -> int | None:
    """The id of the first window whose name has `name`, waiting up to `timeout` seconds
    (a loaded machine starts a software-rendered viewer slowly: 30 s was once too short),
    and no longer once `process` (the program opening it) has exited."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        found = xdotool(env, "search", "--name", name, check=False).split()  # exit 1: none yet
        if found:
            return int(found[0])
        if process is not None and process.poll() is not None:
            return None
        time.sleep(0.25)
    return None


def no_window(process) -> str:
    """Why a program's window never appeared: its exit and the end of its stderr (it is killed
    if it still runs)."""
    if process.poll() is None:
        process.kill()
    _, err = process.communicate(timeout=30)
    err = err.decode(errors="replace") if isinstance(err, bytes) else err or ""
    return f"the window never appeared (exit {process.returncode}): {err[-3000:]}"


class _ClientMessage(ctypes.Structure):
    _fields_ = [
        ("type", ctypes.c_int),
        ("serial", ctypes.c_ulong),
        ("send_event", ctypes.c_int),
        ("display", ctypes.c_void_p),
        ("window", ctypes.c_ulong),
        ("message_type", ctypes.c_ulong),
        ("format", ctypes.c_int),
        ("data", ctypes.c_long * 5),
    ]


class _XEvent(ctypes.Union):
    _fields_ = [("xclient", _ClientMessage), ("pad", ctypes.c_long * 24)]


def close_window(display: str, window: int) -> None:
    """Ask `window` on `display` to close, as a window manager's close button does."""
    x11 = ctypes.CDLL(ctypes.util.find_library("X11") or "libX11.so.6")
    x11.XOpenDisplay.restype = ctypes.c_void_p
    x11.XOpenDisplay.argtypes = [ctypes.c_char_p]
    x11.XInternAtom.restype = ctypes.c_ulong
    x11.XInternAtom.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int]
    x11.XSendEvent.argtypes = [ctypes.c_void_p, ctypes.c_ulong, ctypes.c_int, ctypes.c_long, ctypes.POINTER(_XEvent)]
    x11.XFlush.argtypes = [ctypes.c_void_p]
    x11.XCloseDisplay.argtypes = [ctypes.c_void_p]
    dpy = x11.XOpenDisplay(display.encode())
    if not dpy:
        raise RuntimeError(f"cannot open X display {display}")
    try:
        event = _XEvent()
        event.xclient.type = 33  # ClientMessage
        event.xclient.window = window
        event.xclient.message_type = x11.XInternAtom(dpy, b"WM_PROTOCOLS", 0)
        event.xclient.format = 32
        event.xclient.data[0] = x11.XInternAtom(dpy, b"WM_DELETE_WINDOW", 0)
        event.xclient.data[1] = 0  # CurrentTime
        x11.XSendEvent(dpy, window, 0, 0, ctypes.byref(event))
        x11.XFlush(dpy)
    finally:
        x11.XCloseDisplay(dpy)


def screenshot(display: str):
    """The whole screen of `display` as an (H, W, 3) uint8 array."""
    import numpy as np
    from PIL import ImageGrab

    return np.asarray(ImageGrab.grab(xdisplay=display).convert("RGB"))
