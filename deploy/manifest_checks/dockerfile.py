"""The Dockerfile's runtime stage, which the compose files and Kubernetes manifests must agree
with: its USER, EXPOSEd ports and SHAPEID_* ENV defaults."""


def read_dockerfile(c, path):
    """The runtime stage's USER, EXPOSE'd ports and SHAPEID_* ENV defaults; a missing file is
    a problem, and an image with none of them is checked in its place."""
    image = {"uid": None, "ports": set(), "data_dir": None, "listen": ""}
    if not path.is_file():
        c.error(path.name, "not found: the image's user, ports and defaults are unchecked")
        return image
    lines = path.read_text().replace("\\\n", " ").splitlines()
    for line in lines:
        words = line.split()
        if not words:
            continue
        instruction = words[0].upper()
        if instruction == "FROM":
            image = {"uid": None, "ports": set(), "data_dir": None, "listen": ""}
        elif instruction == "USER":
            user = words[1].split(":")[0]
            image["uid"] = int(user) if user.isdigit() else user
        elif instruction == "EXPOSE":
            image["ports"] |= {int(p.split("/")[0]) for p in words[1:]}
        elif instruction == "ENV":
            for word in words[1:]:
                key, _, value = word.partition("=")
                if key == "SHAPEID_DATA_DIR":
                    image["data_dir"] = value
                elif key == "SHAPEID_LISTEN":
                    image["listen"] = value
    return image


def check_image(c, image):
    """The image runs as a non-root numeric uid and EXPOSEs the gRPC port."""
    if not isinstance(image["uid"], int) or image["uid"] == 0:
        c.error("Dockerfile", f"USER must be a non-zero numeric uid, got {image['uid']!r}")
    if 50051 not in image["ports"]:
        c.error("Dockerfile", "EXPOSE 50051 missing")
