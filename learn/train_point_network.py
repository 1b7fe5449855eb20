#!/usr/bin/python3
"""Trains the point network behind the `learned` descriptor and writes its model file.

A PointNet (a shared per-point MLP, batch norm, ReLU, max pool; Qi et al. 2017) learns to
classify the views shapeid_export_views wrote: every training cloud whole and as the
gallery's own synthetic sensor views, already laid in DFSD's frame. Only the per-point layers
ship (batch norm folded in): the max-pooled feature, scaled to unit length, is the descriptor;
the classifier on top exists only to train it. Augmentation turns each view the ways its frame
could have fallen (the ambiguous bits), jitters, scales and thins it.

  learn/train_point_network.py --views build/learn/mn10-box.views \\
      --out core/descriptors/models/pointnet-box-v1.spn \\
      --golden core/descriptors/testdata/pointnet-box-v1.golden

Runs on Debian's python3-torch (CPU); install libopenblas0-pthread first (learn/README.md).
Deterministic for a seed on one machine and thread count.
"""

import argparse
import datetime
import math
import os
import sys
import time

import numpy as np
import torch
from torch import nn

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import point_network_file  # noqa: E402


class PointNet(nn.Module):
    def __init__(self, widths, classes, head_width, dropout):
        super().__init__()
        layers, previous = [], 3
        for width in widths:
            layers += [nn.Conv1d(previous, width, 1), nn.BatchNorm1d(width), nn.ReLU()]
            previous = width
        self.points = nn.Sequential(*layers)
        self.head = nn.Sequential(
            nn.Linear(previous, head_width), nn.BatchNorm1d(head_width), nn.ReLU(),
            nn.Dropout(dropout), nn.Linear(head_width, classes))

    def embed(self, x):  # x: batch x 3 x points
        return self.points(x).max(dim=2).values

    def forward(self, x):
        return self.head(self.embed(x))

    def folded_layers(self):
        """The per-point layers with batch norm folded in, as the model file stores them."""
        folded = []
        modules = list(self.points)
        for i in range(0, len(modules), 3):
            conv, norm = modules[i], modules[i + 1]
            scale = norm.weight / torch.sqrt(norm.running_var + norm.eps)
            weight = conv.weight[:, :, 0] * scale[:, None]
            bias = (conv.bias - norm.running_mean) * scale + norm.bias
            folded.append((weight.detach().numpy().astype(np.float32),
                           bias.detach().numpy().astype(np.float32)))
        return folded


def padded(points, size):
    """m x 3 -> size x 3 by repeating points cyclically: the max pool is unchanged."""
    m = points.shape[0]
    return points[np.arange(size) % m]


def rotation_matrices(count, sigma, generator):
    axis = torch.randn(count, 3, generator=generator)
    axis = axis / axis.norm(dim=1, keepdim=True)
    angle = torch.randn(count, generator=generator) * sigma
    k = torch.zeros(count, 3, 3)
    k[:, 0, 1], k[:, 0, 2], k[:, 1, 2] = -axis[:, 2], axis[:, 1], -axis[:, 0]
    k = k - k.transpose(1, 2)
    s, c = torch.sin(angle)[:, None, None], torch.cos(angle)[:, None, None]
    return torch.eye(3)[None] + s * k + (1 - c) * (k @ k)


def augment(x, ambiguous, generator, args):
    """x: batch x points x 3 in the frame; ambiguous: the frame's guesses (CanonicalPoints)."""
    b, p, _ = x.shape
    x = x.clone()
    for axis in range(3):
        flip = ((ambiguous >> axis) & 1).bool() & (torch.rand(b, generator=generator) < 0.5)
        x[flip, :, axis] = -x[flip, :, axis]
    for bit, (i, j) in ((3, (0, 1)), (4, (1, 2))):
        swap = ((ambiguous >> bit) & 1).bool() & (torch.rand(b, generator=generator) < 0.5)
        x[swap] = x[swap][:, :, [j if a == i else i if a == j else a for a in range(3)]]
    x = x @ rotation_matrices(b, math.radians(args.tilt), generator).transpose(1, 2)
    scale = 1 + (torch.rand(b, 1, 3, generator=generator) * 2 - 1) * args.scale
    x = x * scale + torch.randn(x.shape, generator=generator) * args.jitter
    # Thinning: keep a random share of the points, the rest become copies of kept ones.
    keep = torch.rand(b, 1, generator=generator) * (1 - args.min_keep) + args.min_keep
    dropped = torch.rand(b, p, generator=generator) > keep
    dropped[:, 0] = False
    x[dropped] = x[:, :1].expand(b, p, 3)[dropped]
    return x


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--views", required=True)
    parser.add_argument("--out", required=True)
    parser.add_argument("--golden")
    parser.add_argument("--name", default="pointnet-box-v1")
    parser.add_argument("--frame", default="box", choices=["box", "upright"])
    parser.add_argument("--points", type=int, default=512, help="max_points")
    parser.add_argument("--widths", default="64,128,256")
    parser.add_argument("--head", type=int, default=128)
    parser.add_argument("--dropout", type=float, default=0.4)
    parser.add_argument("--epochs", type=int, default=40)
    parser.add_argument("--per-object", type=int, default=3,
                        help="views of each object drawn per epoch")
    parser.add_argument("--batch", type=int, default=64)
    parser.add_argument("--lr", type=float, default=2e-3)
    parser.add_argument("--wd", type=float, default=1e-4)
    parser.add_argument("--tilt", type=float, default=6.0, help="degrees of frame jitter")
    parser.add_argument("--scale", type=float, default=0.12)
    parser.add_argument("--jitter", type=float, default=0.01)
    parser.add_argument("--min-keep", type=float, default=0.35)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--command", default=" ".join(sys.argv))
    args = parser.parse_args()

    torch.set_num_threads(args.threads)
    torch.manual_seed(args.seed)
    generator = torch.Generator().manual_seed(args.seed)
    started = time.time()
    labels, label, obj, view, ambiguous, points = point_network_file.read_views(args.views)
    x_all = torch.from_numpy(np.stack([padded(p, args.points) for p in points]))
    y_all = torch.from_numpy(label)
    amb_all = torch.from_numpy(ambiguous)
    # The gallery's own held-out slice: every tenth object, all its views (the training side's
    # simulator, so a sanity figure, never the test figure).
    held = torch.from_numpy(obj % 10 == 0)
    train_objects = np.unique(obj[~(obj % 10 == 0)])
    by_object = {o: np.nonzero(obj == o)[0] for o in train_objects}
    print("%d views of %d objects, %d labels, read in %.0f s" %
          (len(points), len(np.unique(obj)), len(labels), time.time() - started), flush=True)

    widths = [int(w) for w in args.widths.split(",")]
    model = PointNet(widths, len(labels), args.head, args.dropout)
    optimizer = torch.optim.AdamW(model.parameters(), lr=args.lr, weight_decay=args.wd)
    steps_per_epoch = math.ceil(len(train_objects) * args.per_object / args.batch)
    schedule = torch.optim.lr_scheduler.OneCycleLR(
        optimizer, max_lr=args.lr, total_steps=args.epochs * steps_per_epoch)
    loss_of = nn.CrossEntropyLoss(label_smoothing=0.1)
    rng = np.random.default_rng(args.seed)

    def held_out_accuracy():
        model.eval()
        index = torch.nonzero(held)[:, 0]
        correct = 0
        with torch.no_grad():
            for start in range(0, len(index), 256):
                part = index[start:start + 256]
                logits = model(x_all[part].transpose(1, 2))
                correct += (logits.argmax(1) == y_all[part]).sum().item()
        return correct / max(len(index), 1)

    for epoch in range(args.epochs):
        model.train()
        chosen = np.concatenate([rng.choice(by_object[o], size=args.per_object)
                                 for o in train_objects])
        rng.shuffle(chosen)
        total, correct, seen = 0.0, 0, 0
        for start in range(0, len(chosen), args.batch):
            part = torch.from_numpy(chosen[start:start + args.batch])
            if len(part) < 2:
                continue
            x = augment(x_all[part], amb_all[part], generator, args)
            logits = model(x.transpose(1, 2))
            loss = loss_of(logits, y_all[part])
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            schedule.step()
            total += loss.item() * len(part)
            correct += (logits.argmax(1) == y_all[part]).sum().item()
            seen += len(part)
        line = "epoch %d: loss %.3f, train %.1f %%" % (epoch + 1, total / seen, 100 * correct / seen)
        if (epoch + 1) % 5 == 0 or epoch + 1 == args.epochs:
            line += ", held-out views %.1f %%" % (100 * held_out_accuracy())
        print(line + ", %.0f s" % (time.time() - started), flush=True)

    model.eval()
    held_accuracy = held_out_accuracy()
    layers = model.folded_layers()
    card = "\n".join([
        "# %s" % args.name,
        "",
        "A PointNet (shared per-point MLP %s, max pool; batch norm folded in) trained by "
        "learn/train_point_network.py; its embedding (%d values, unit length) is the "
        "`learned:model=%s` descriptor." % ("3-" + "-".join(map(str, widths)), widths[-1],
                                             args.name),
        "",
        "- Frame: DFSD's frame=%s; at most %d points (a fixed stride)." % (args.frame, args.points),
        "- Data: %s: %d views of %d training objects, %d labels (%s)." % (
            os.path.basename(args.views), len(points), len(np.unique(obj)), len(labels),
            ", ".join(labels)),
        "- Training: %d epochs x %d views per object, batch %d, AdamW lr %g wd %g, one-cycle, "
        "label smoothing 0.1, dropout %g; augmentation: the frame's ambiguous flips and swaps, "
        "tilt %g deg, scale +-%g, jitter %g, thinning to >= %g; seed %d." % (
            args.epochs, args.per_object, args.batch, args.lr, args.wd, args.dropout, args.tilt,
            args.scale, args.jitter, args.min_keep, args.seed),
        "- Held-out slice (every tenth training object, the trainer's own simulated views; a "
        "sanity figure, not a test figure): %.1f %%." % (100 * held_accuracy),
        "- Trained %s in %.0f s on %d CPU threads (torch %s)." % (
            datetime.date.today().isoformat(), time.time() - started, args.threads,
            torch.__version__),
        "- Command: %s" % args.command,
        "",
        "Accuracy on independent views: docs/accuracy.md, \"A learned descriptor\".",
    ])
    point_network_file.write_model(args.out, args.name, card, args.frame, args.points, layers)
    print(card)
    if args.golden:
        # Golden sets: views of several sizes, unpadded; torch embeds them padded, as trained.
        picks = [i for i in np.argsort([p.shape[0] for p in points])[:: len(points) // 7]][:8]
        sets, embeddings = [], []
        with torch.no_grad():
            for i in picks:
                x = torch.from_numpy(padded(points[i], args.points))[None].transpose(1, 2)
                e = model.embed(x)[0]
                embeddings.append((e / e.norm()).numpy())
                sets.append(points[i][: args.points])
        point_network_file.write_golden(args.golden, sets, embeddings)
        print("golden: %d point sets to %s" % (len(sets), args.golden))


if __name__ == "__main__":
    main()
