"""The kind of special file a path is (`avsim.file_kinds`), behind every "not a regular file" refusal."""

from __future__ import annotations

import os
import socket

from avsim.file_kinds import special_file_kind


def test_a_regular_file_a_folder_and_a_missing_path_are_no_special_kind(tmp_path):
    (tmp_path / "a.txt").write_text("a")
    assert special_file_kind(tmp_path / "a.txt") is None
    assert special_file_kind(tmp_path) is None
    assert special_file_kind(tmp_path / "missing") is None
    assert special_file_kind(str(tmp_path / "missing" / "below")) is None
    assert special_file_kind("") is None


def test_a_device_a_pipe_and_a_socket_are_named(tmp_path):
    os.mkfifo(tmp_path / "pipe")
    assert special_file_kind(tmp_path / "pipe") == "a pipe (FIFO)"
    assert special_file_kind("/dev/null") == "a device"  # a character device
    with socket.socket(socket.AF_UNIX) as server:
        server.bind(str(tmp_path / "sock"))
        assert special_file_kind(tmp_path / "sock") == "a socket"


def test_a_link_is_followed_as_path_is_file_follows_it(tmp_path):
    os.mkfifo(tmp_path / "pipe")
    (tmp_path / "to_pipe").symlink_to(tmp_path / "pipe")
    (tmp_path / "dangling").symlink_to(tmp_path / "missing")
    assert special_file_kind(tmp_path / "to_pipe") == "a pipe (FIFO)"
    assert special_file_kind(tmp_path / "dangling") is None
