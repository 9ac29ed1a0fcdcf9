"""Check what the built distributions contain (run by .ci/wheel-check): each wheel installs one
import package and nothing else, carries its data files, licence and metadata; each sdist
carries what it needs to build that wheel again. Prints a summary; exits 1 on a problem."""

from __future__ import annotations

import sys
import tarfile
import zipfile
from email.parser import HeaderParser
from pathlib import Path

EXPECTED = {
    # distribution: (import package, files that must be in it, requirement on the framework)
    "anytime_compose": ("anytime", ["anytime/py.typed", "anytime/dsl/grammar.lark"], None),
    "anytime_navigation": (
        "anytime_navigation",
        [
            "anytime_navigation/py.typed",
            "anytime_navigation/schemas/navigation.any",
            "anytime_navigation/schemas/obstacles.any",
            *(
                f"anytime_navigation/profiles/{m}.yaml"
                for m in ("a-star", "detour-left", "detour-right", "find-path", "wait")
            ),
            "anytime_navigation/profiles/get-domain-description.yaml",
            "anytime_navigation/maps/README.md",
            "anytime_navigation/maps/arena.map",
            "anytime_navigation/maps/arena.map.scen",
        ],
        "anytime-compose",
    ),
    "anytime_routing": (
        "anytime_routing",
        [
            "anytime_routing/py.typed",
            "anytime_routing/schemas/routing.any",
            *(
                f"anytime_routing/profiles/{m}.yaml"
                for m in ("estimate-demand", "cluster-stops", "plan-tours", "insert-tours")
            ),
        ],
        "anytime-compose",
    ),
    "anytime_motion": (
        "anytime_motion",
        [
            "anytime_motion/py.typed",
            "anytime_motion/schemas/motion.any",
            *(
                f"anytime_motion/profiles/{m}.yaml"
                for m in ("sense-obstacles", "rrt-star", "bit-star", "shorten-path")
            ),
        ],
        "anytime-compose",
    ),
}


def check_wheel(path: Path, problems: list[str]) -> None:
    name = path.name.split("-")[0]
    package, required, requirement = EXPECTED[name]
    names = zipfile.ZipFile(path).namelist()
    tops = sorted({n.split("/")[0] for n in names})
    info = [t for t in tops if t.endswith(".dist-info")]
    if tops != sorted([package, *info]):
        problems.append(f"{path.name}: top-level entries {tops}, expected only {package}/")
    for file in required:
        if file not in names:
            problems.append(f"{path.name}: missing {file}")
    if not any(n.endswith(".dist-info/licenses/LICENSE") for n in names):
        problems.append(f"{path.name}: no LICENSE in its .dist-info/licenses")
    metadata = HeaderParser().parsestr(
        zipfile.ZipFile(path).read(f"{info[0]}/METADATA").decode("utf-8")
    )
    if metadata.get("License-Expression") != "MIT":
        problems.append(f"{path.name}: License-Expression is {metadata.get('License-Expression')}")
    for field in ("Author", "Summary", "Requires-Python"):
        if not metadata.get(field):
            problems.append(f"{path.name}: no {field}")
    if not metadata.get_all("Classifier"):
        problems.append(f"{path.name}: no classifiers")
    if metadata.get("Description-Content-Type") != "text/markdown":
        problems.append(f"{path.name}: no markdown readme")
    requires = metadata.get_all("Requires-Dist") or []
    if requirement and not any(r.startswith(requirement) for r in requires):
        problems.append(f"{path.name}: does not require {requirement}")
    files = [n for n in names if not n.endswith("/") and not n.split("/")[0].endswith(".dist-info")]
    by_suffix: dict[str, int] = {}
    for n in files:
        suffix = Path(n).suffix or Path(n).name
        by_suffix[suffix] = by_suffix.get(suffix, 0) + 1
    listed = ", ".join(f"{count} {suffix}" for suffix, count in sorted(by_suffix.items()))
    print(f"{path.name}: {package}/ only; {listed}")


def check_sdist(path: Path, problems: list[str]) -> None:
    name = path.name.split("-")[0]
    package, required, _ = EXPECTED[name]
    with tarfile.open(path) as archive:
        names = {"/".join(n.split("/")[1:]) for n in archive.getnames()}
    for file in ["LICENSE", "README.md", "pyproject.toml", *required]:
        if file not in names:
            problems.append(f"{path.name}: missing {file}")
    print(f"{path.name}: {len(names)} entries")


def main(folder: str) -> int:
    problems: list[str] = []
    dist = Path(folder)
    wheels, sdists = sorted(dist.glob("*.whl")), sorted(dist.glob("*.tar.gz"))
    if {w.name.split("-")[0] for w in wheels} != set(EXPECTED):
        problems.append(f"expected a wheel of each of {sorted(EXPECTED)}, got {wheels}")
    if {s.name.split("-")[0] for s in sdists} != set(EXPECTED):
        problems.append(f"expected an sdist of each of {sorted(EXPECTED)}, got {sdists}")
    for wheel in wheels:
        check_wheel(wheel, problems)
    for sdist in sdists:
        check_sdist(sdist, problems)
    for problem in problems:
        print(f"check_distributions: {problem}", file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
