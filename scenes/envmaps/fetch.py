#!/usr/bin/env python3
"""Regenerates the environment maps in scenes/envmaps/ from the npm package @pmndrs/assets.

Python 3 standard library only (npm is needed only to download the package). The package holds
each map as an ES module `hdri/<name>.exr.js` whose default export is a data URI,
`export default 'data:application/exr;base64,...'`; this script decodes the base64 to the .exr
file byte for byte (no re-encoding) and checks its SHA-256 against the one recorded below.

    python3 scenes/envmaps/fetch.py                          # runs `npm pack` in a temp folder
    python3 scenes/envmaps/fetch.py --tarball /tmp/pmndrs-assets-1.7.0.tgz
    python3 scenes/envmaps/fetch.py --tarball T.tgz --out /tmp/maps dawn park   # other maps

The tarball of @pmndrs/assets 1.7.0 has sha1 46e14926f6a40b44ac44bde8140b423148b9221f (npm's
dist.shasum). See README.md here for the maps' origin, licence and statistics.
"""

import argparse
import base64
import hashlib
import os
import subprocess
import sys
import tarfile
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
PACKAGE = "@pmndrs/assets@1.7.0"
TARBALL_SHA1 = "46e14926f6a40b44ac44bde8140b423148b9221f"

# SHA-256 of the decoded .exr files committed here.
MAPS = {
    "studio": "08038ed9159c24bb732d2218dafa09cef2abaa44f9ce11ec511d87c842d88fad",
    "sunset": "d09a4d7581f5454f13c3da3c323a231d00a34e60200de7654a895d2d41a7ceb7",
    "sky": "a72412700b91a49080a582420476d2ab9a1e8fd181031f4ae7ec5e2596addc2a",
}

PREFIX = "data:application/exr;base64,"


def npm_pack(folder):
    subprocess.run(["npm", "pack", PACKAGE], cwd=folder, check=True, stdout=subprocess.DEVNULL)
    names = [n for n in os.listdir(folder) if n.endswith(".tgz")]
    if len(names) != 1:
        sys.exit("npm pack left %r in %s; expected one .tgz" % (names, folder))
    return os.path.join(folder, names[0])


def decode(module_text, member):
    """The bytes of the data URI in `export default '<data URI>'`."""
    start = module_text.find("'")
    end = module_text.rfind("'")
    uri = module_text[start + 1:end] if 0 <= start < end else ""
    if not uri.startswith(PREFIX):
        sys.exit("%s: expected `export default '%s...'`" % (member, PREFIX))
    return base64.b64decode(uri[len(PREFIX):], validate=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("names", nargs="*", default=sorted(MAPS),
                    help="maps (default: %s)" % ", ".join(sorted(MAPS)))
    ap.add_argument("--tarball", help="the package tarball (default: download it with npm pack)")
    ap.add_argument("--out", default=HERE,
                    help="folder to write <name>.exr to (default: scenes/envmaps)")
    args = ap.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        tarball = args.tarball or npm_pack(tmp)
        sha1 = hashlib.sha1(open(tarball, "rb").read()).hexdigest()
        if sha1 != TARBALL_SHA1:
            print("warning: %s has sha1 %s, not %s (%s)" % (tarball, sha1, TARBALL_SHA1, PACKAGE),
                  file=sys.stderr)
        os.makedirs(args.out, exist_ok=True)
        with tarfile.open(tarball, "r:gz") as tar:
            for name in args.names:
                member = "package/hdri/%s.exr.js" % name
                try:
                    text = tar.extractfile(member).read().decode("ascii")
                except KeyError:
                    sys.exit("%s has no %s" % (tarball, member))
                data = decode(text, member)
                if data[:4] != b"\x76\x2f\x31\x01":
                    sys.exit("%s: the decoded data is not an OpenEXR file" % member)
                digest = hashlib.sha256(data).hexdigest()
                if name in MAPS and digest != MAPS[name]:
                    sys.exit("%s: decoded SHA-256 %s, expected %s" % (member, digest, MAPS[name]))
                path = os.path.join(args.out, name + ".exr")
                with open(path, "wb") as f:
                    f.write(data)
                print("wrote %s (%d bytes, sha256 %s)" % (path, len(data), digest))


if __name__ == "__main__":
    main()
