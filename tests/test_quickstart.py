"""``make demo`` trains nothing: the quickstart's SEN learner names the d = 20% MountainCar
encoder of paper-mountaincar.yaml, which is committed under results/encoders/. And the
README shows the quickstart suite as it is."""

import re
import subprocess
from pathlib import Path

from senbench.encoders import complete
from senbench.plugin.manager import registries
from senbench.suite import load_suite

ROOT = Path(__file__).parent.parent
ENCODER = "ea0241bd6c34ad4a"


def encoder_ids(suite: str) -> set[str]:
    regs = registries()
    cells = load_suite(ROOT / "suites" / suite, regs).cells
    return {complete(c.encoder_request(), regs).id for c in cells if c.encoder_request()}


def test_the_quickstart_uses_the_committed_paper_encoder():
    assert encoder_ids("quickstart.yaml") == {ENCODER}
    assert encoder_ids("paper-mountaincar.yaml") == {ENCODER}
    folder = ROOT / "results" / "encoders" / ENCODER
    assert (folder / "model.pt").is_file() and (folder / "spec.json").is_file()
    tracked = subprocess.run(["git", "ls-files", f"results/encoders/{ENCODER}"], cwd=ROOT,
                             capture_output=True, text=True, check=False)
    if tracked.returncode == 0:  # in a git checkout: committed, so a fresh clone has it
        assert f"results/encoders/{ENCODER}/model.pt" in tracked.stdout.split()


def test_the_readme_shows_the_quickstart_suite_as_it_is():
    readme = (ROOT / "README.md").read_text()
    blocks = [b for b in re.findall(r"^```yaml\n(.*?)^```$", readme, re.MULTILINE | re.DOTALL)
              if b.startswith("name: quickstart\n")]
    assert len(blocks) == 1
    assert (ROOT / "suites" / "quickstart.yaml").read_text().endswith(blocks[0])
