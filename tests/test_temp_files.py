"""A writer killed mid-write leaves a temp file beside the results; the next run removes it
only once its writer (on this host) is dead."""

import subprocess
import time


def test_a_temp_file_of_a_killed_writer_not_yet_reaped_is_removed(tmp_path):
    from senbench.results.store import remove_stray_temp_files

    writer = subprocess.Popen(["sleep", "30"])
    stray = tmp_path / f".abcdef.{writer.pid}.tmp"
    stray.write_text("half a file")
    assert remove_stray_temp_files(tmp_path) == 0  # a live writer's file stays
    writer.kill()
    time.sleep(0.2)  # killed, not yet waited for: a zombie
    try:
        assert remove_stray_temp_files(tmp_path) == 1 and not stray.exists()
    finally:
        writer.wait()


def test_only_this_hosts_dead_writers_temp_files_are_removed(tmp_path):
    from senbench.results.store import remove_stray_temp_files, writer_tag

    writer = subprocess.Popen(["sleep", "0"])
    writer.wait()  # a dead writer's pid
    host = writer_tag().partition("-")[2]
    here = tmp_path / f".abcdef.{writer.pid}-{host}.tmp"
    there = tmp_path / f".abcdef.{writer.pid}-other-node_7.tmp"  # on a machine sharing it
    mine = tmp_path / f".fedcba.{writer_tag()}.tmp"  # this process's: a stray of its own
    odd = tmp_path / ".notes.txt.tmp"  # not a cell's: whose it is cannot be told
    for path in (here, there, mine, odd):
        path.write_text("half a file")
    assert remove_stray_temp_files(tmp_path) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([there.name, odd.name])


def test_host_names_that_differ_give_different_temp_file_tags():
    from senbench.results.store import writer_tag

    hosts = ["node.1", "node_1", "node-1", "node_2e_1", "nöde.1", "n"]
    tags = [writer_tag(h).partition("-")[2] for h in hosts]
    assert len(set(tags)) == len(hosts)
    assert tags[0] == "node_2e_1" and tags[2] == "node-1"


def test_a_dead_writers_temp_file_in_the_older_host_tag_is_removed_too(tmp_path, monkeypatch):
    from senbench.results import store as results

    writer = subprocess.Popen(["sleep", "0"])
    writer.wait()
    monkeypatch.setattr(results.socket, "gethostname", lambda: "node.1")
    names = [f".abcdef.{writer.pid}-node_2e_1.tmp",  # this host's tag
             f".abcdef.{writer.pid}-node_1.tmp",  # the one earlier builds wrote for it
             f".abcdef.{writer.pid}-node_5f_1.tmp"]  # host node_1's: not this one's
    for name in names:
        (tmp_path / name).write_text("half a file")
    assert results.remove_stray_temp_files(tmp_path) == 2
    assert [p.name for p in tmp_path.iterdir()] == [names[2]]
