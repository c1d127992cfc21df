"""A published release as the field's tools read it, for tests/cli.rs: MLCommons' mlcroissant
loads the records of its croissant.json, PyYAML parses its dataset card's front matter and
rmvp.read_release reads each split. Prints one JSON object that the Rust test compares with
rmvp's own reading of the same release. Usage: release_check.py RELEASE"""

import json
import os
import sys

import mlcroissant
import yaml

import rmvp


def plain(value):
    """A record's value as JSON has it (mlcroissant gives text as bytes)."""
    return value.decode() if isinstance(value, bytes) else value


def main(release: str) -> None:
    dataset = mlcroissant.Dataset(jsonld=os.path.join(release, "croissant.json"))
    records = {
        name: [{key.split("/", 1)[1]: plain(v) for key, v in record.items()} for record in dataset.records(name)]
        for name in ("views", "objects")
    }
    card = open(os.path.join(release, "README.md"), encoding="utf-8").read()
    assert card.startswith("---\n"), "the card has no front matter"
    front_matter = yaml.safe_load(card.split("---\n")[1])
    splits = {
        split: {name: [view.name for view in scene.views] for name, scene in rmvp.read_release(release, split).items()}
        for split in rmvp.SPLITS
    }
    print(json.dumps({"records": records, "front_matter": front_matter, "read_release": splits}))


if __name__ == "__main__":
    main(sys.argv[1])
