"""The ``frontal3d`` command line.

Every foreseen failure is printed as one line, ``frontal3d: error: <cause>``, with a
non-zero exit; ``--debug`` shows the traceback of unforeseen ones.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path
from typing import Any, Sequence

from frontal3d import __version__
from frontal3d.config import find_config_path, load_config
from frontal3d.errors import ConfigError, Frontal3DError, NotFrontalError
from frontal3d.plugins import Plugins


def main(argv: Sequence[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    if not args.debug:
        _quiet_opencv()
    if getattr(args, "verbose", False):
        logging.getLogger("frontal3d").setLevel(logging.INFO)
    if not hasattr(args, "run"):
        parser.print_help()
        return 1
    try:
        _check_output(args)
        return int(args.run(args) or 0)
    except Frontal3DError as exc:
        print(f"frontal3d: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except OSError as exc:  # the file system said no (a full disk, a path through a file): the user's to fix
        if args.debug:
            raise
        where = f" {exc.filename}" if exc.filename else ""
        print(f"frontal3d: error: cannot use{where}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("frontal3d: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # unforeseen: one line unless --debug
        if args.debug:
            raise
        print(f"frontal3d: internal error: {type(exc).__name__}: {exc} (run with --debug for the traceback)", file=sys.stderr)
        return 3


def _quiet_opencv() -> None:
    """OpenCV logs its decoders' complaints (a corrupt TIFF: four lines) on stderr; the CLI says
    what went wrong itself, in one line. ``--debug`` keeps them."""
    import cv2

    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)


def _check_output(args: argparse.Namespace) -> None:
    """Fail before the work, not after it, when ``-o`` cannot be written (a path through a file, no permission)."""
    from frontal3d.stages.export import check_output_folder

    out = getattr(args, "out", None)
    if out is not None:
        check_output_folder(out.parent if getattr(args, "out_is_file", False) else out)


_MESHES_HELP = "folder of ground-truth *.glb in the family's canonical frame"


def _add_set_option(parser: argparse.ArgumentParser, example: str) -> None:
    """The ``--set KEY=VALUE`` option every command that runs the pipeline takes."""
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help=f"override a family setting, e.g. --set {example} (value parsed as TOML)")


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="frontal3d",
        description="Turn one frontal photo of an object into a textured, watertight 3D mesh by warping a per-family template.",
        epilog="Run `frontal3d COMMAND --help` for a command's options.",
    )
    parser.add_argument("--version", action="version", version=f"frontal3d {__version__}")
    parser.add_argument("--config", type=Path, help="plugins.toml to use (default: $FRONTAL3D_CONFIG, then ./plugins.toml)")
    parser.add_argument("--debug", action="store_true", help="show tracebacks of unexpected errors")
    sub = parser.add_subparsers(title="commands", metavar="COMMAND")

    p = sub.add_parser("reconstruct", help="reconstruct 3D meshes from photos", description="Reconstruct a textured, watertight mesh from each frontal photo. Writes OUTDIR/<image stem>/model.glb, model.obj (+ .mtl, textures), preview.png and report.json. Of several separate objects in a photo, the largest the classifier chain accepts is reconstructed; --all reconstructs each, into OUTDIR/<image stem>_<k>/ (k = 1 for the largest).")
    p.add_argument("images", nargs="+", type=Path, metavar="IMAGE", help="input photo(s): PNG/JPG; an RGBA PNG's alpha is used as the object mask")
    p.add_argument("--family", default="auto", help="family name (see `frontal3d families`), or auto to let the classifier chain pick (default)")
    p.add_argument("--subtype", help="skip the subtype classifier and use this subtype's template")
    p.add_argument("--mask", type=Path, help="object mask (non-zero = object); only with a single IMAGE")
    p.add_argument("--occluder-mask", type=Path, help="mask of things in front of the object (hands, stands); only with a single IMAGE")
    p.add_argument("--all", action="store_true", help="reconstruct each separate object the classifier chain accepts, into OUTDIR/<stem>_<k>/ (k = 1 for the largest)")
    p.add_argument("-o", "--out", type=Path, default=Path("frontal3d-out"), help="output folder (default: ./frontal3d-out)")
    _add_set_option(p, "working_resolution=400")
    p.add_argument("-v", "--verbose", action="store_true", help="log each stage and write intermediate maps to OUTDIR/<stem>/debug/ (with occluders or people "
                   "touching the object, occlusion_sheet.png pictures who stands in front, what was rebuilt and the rebuilt regions); "
                   "for a photo the classifier chain turns down, the outline it judged to OUTDIR/<stem>_turned_down.png")
    p.set_defaults(run=_cmd_reconstruct)

    p = sub.add_parser("families", help="list installed families, subtypes, views and regions")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(run=_cmd_families)

    p = sub.add_parser("plugins", help="list installed plugins and the hooks they implement")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(run=_cmd_plugins)

    p = sub.add_parser("new-family", help="scaffold a third-party family plugin package", description="Create a ready-to-install package for a new object family: pyproject with the entry point, hook implementations, family.yaml and a test. Then `pip install -e DIR` and it shows up in `frontal3d families`.")
    p.add_argument("name", help="family name, e.g. chair (lower case, letters, digits and _)")
    p.add_argument("--template", type=Path, help="a mesh (GLB/OBJ/PLY/STL) in the canonical frame to ship as the template")
    p.add_argument("--view", choices=["front", "side", "top"], default="front", help="which view of the object the photos show (default: front)")
    p.add_argument("-o", "--out", type=Path, help="folder to create (default: ./frontal3d-<name>)")
    p.set_defaults(run=_cmd_new_family)

    p = sub.add_parser("template", help="build or picture templates")
    tsub = p.add_subparsers(title="template commands", metavar="ACTION")
    t = tsub.add_parser("build", help="check a user mesh, turn it into a template, render and cache it")
    t.add_argument("mesh", type=Path, help="mesh file (GLB/OBJ/PLY/STL) in the family's canonical frame")
    t.add_argument("--family", required=True)
    t.add_argument("--subtype", required=True)
    t.add_argument("--regions", type=Path, help="YAML/JSON mapping of the mesh's group/material/colour names to region names")
    t.add_argument("-o", "--out", type=Path, help="also write a contact sheet PNG here")
    t.set_defaults(run=_cmd_template_build, out_is_file=True)
    t = tsub.add_parser("show", help="write a contact sheet of a template: views, depth, normals, regions, landmarks")
    t.add_argument("which", metavar="FAMILY/SUBTYPE")
    t.add_argument("-o", "--out", type=Path, required=True, help="PNG to write")
    t.set_defaults(run=_cmd_template_show, out_is_file=True)

    p = sub.add_parser("evaluate", help="score reconstructions against ground-truth meshes (the paper's protocol)", description="For each ground-truth mesh (canonical frame), reconstruct from its frontal render and compare: voxel IoU (128^3, ICP-aligned), Chamfer-L1 and F-score@0.1 (each mesh centred on its box; also after the IoU's ICP alignment, as a second reading of the paper). Writes metrics.csv, summary.csv and boxplots.png.")
    p.add_argument("--family", required=True)
    p.add_argument("--meshes", type=Path, required=True, help=_MESHES_HELP)
    p.add_argument("--renders", type=Path, help="folder of <id>.png/<id>_mask.png/<id>.json frontal renders (default: render them)")
    p.add_argument("--method", choices=["template", "slab"], default="template", help="template (the pipeline) or slab (the plain extrusion baseline)")
    p.add_argument("--limit", type=int, help="only the first N meshes")
    _add_set_option(p, "frontal_threshold=0")
    p.add_argument("-o", "--out", type=Path, default=Path("frontal3d-eval"), help="output folder")
    p.add_argument("-v", "--verbose", action="store_true", help="also write a sheet per mesh to OUT/sheets: truth and reconstruction "
                   "as the point metrics compare them, seen from three sides")
    p.set_defaults(run=_cmd_evaluate)

    p = sub.add_parser("evaluate-occlusion", help="score reconstructions of renders with arms or people pasted in front (issue 7's protocols)", description="Paste occluders over each frontal render (10-30 % of the object) and reconstruct from the visible mask (with --segment, from the composite alone): arms = procedural skin-toned forearms and hands, their mask given as the occluder mask; people = people cut out of public-domain photos shipped with skimage and matplotlib, as a guitarist (body behind, an arm in front) or whole in front, no occluder mask given (each also run with its true mask for reference). Reports each metric's change against the unoccluded reconstruction, rejections and occluder pixels left in the texture (in the whole front half of the atlas, and on the model only). Writes composites.csv, summary.csv and images/.")
    p.add_argument("--family", required=True)
    p.add_argument("--meshes", type=Path, required=True, help=_MESHES_HELP)
    p.add_argument("--renders", type=Path, required=True, help="folder of <id>.png/<id>_mask.png/<id>.json frontal renders")
    p.add_argument("--occluders", choices=["arms", "people"], required=True, help="arms (mask given) or people (found by the detectors)")
    p.add_argument("--per-object", type=int, default=5, help="composites per render (default: 5)")
    p.add_argument("--seed", type=int, default=0, help="placement seed; the same seed gives the same composites")
    p.add_argument("--limit", type=int, help="only the first N meshes")
    p.add_argument("--every", type=int, default=1, help="score every N-th mesh of the sorted listing, under the composites the whole run gives it (default: 1)")
    p.add_argument("--offset", type=int, default=0, help="start at this index of the listing, below --every (default: 0; 1 with --every 2 = the odd half)")
    p.add_argument("--segment", action="store_true", help="give no object mask: segment each composite (and its clean render) as reconstruct does with a photo")
    _add_set_option(p, "working_resolution=400")
    p.add_argument("-o", "--out", type=Path, default=Path("frontal3d-eval-occlusion"), help="output folder")
    p.set_defaults(run=_cmd_evaluate_occlusion)

    p = sub.add_parser("evaluate-masks", help="score the segmenter chain on renders composited over procedural backgrounds", description="Composite each RGBA render (alpha = silhouette) over seeded procedural backgrounds with sensor noise, segment it as reconstruct does with no mask given, and score the mask IoU against the alpha. Writes masks.csv (per image) and summary.csv (per background); backgrounds are defined in docs/results.md.")
    p.add_argument("--family", required=True)
    p.add_argument("--renders", type=Path, required=True, help="folder of <id>.png RGBA renders")
    p.add_argument("--backgrounds", help="comma-separated subset of plain,gradient,noise,mild,blobs (default: all)")
    p.add_argument("--every", type=int, default=1, help="use every N-th render of the sorted listing (default: 1)")
    p.add_argument("--offset", type=int, default=0, help="start at this index of the listing, below --every (default: 0; 1 with --every 2 = the odd half)")
    p.add_argument("--seed", type=int, default=0, help="seed of the backgrounds and the sensor noise")
    _add_set_option(p, "shape_prior=true")
    p.add_argument("-o", "--out", type=Path, default=Path("frontal3d-masks"), help="output folder (default: ./frontal3d-masks)")
    p.add_argument("-v", "--verbose", action="store_true", help="also write a debug sheet per image to OUT/debug (input | mask | truth)")
    p.set_defaults(run=_cmd_evaluate_masks)

    p = sub.add_parser("evaluate-gate", help="measure the frontal gate on ground-truth meshes turned away from the canonical view", description="Render each ground-truth mesh (canonical frame) turned about image-up and image-right by each angle, both ways, as a shaded frontal image, run the classifier chain on it with the true mask given, and print the acceptance per angle and the balanced accuracy (0 deg, and 0-10 deg, accepted vs >= 30 deg rejected). With --synth, judges the samples of a `frontal3d synth` folder by their frontal/turned labels instead (the held-out synthetic figures margins are chosen on). Writes OUT/gate.csv (one row per view or sample, with the gate's reason) and OUT/summary.txt.")
    p.add_argument("--family", required=True)
    source = p.add_mutually_exclusive_group(required=True)
    source.add_argument("--meshes", type=Path, help=_MESHES_HELP)
    source.add_argument("--synth", type=Path, help="a `frontal3d synth` folder instead: judge its samples by their frontal/turned labels")
    p.add_argument("--subtype", help="judge against this subtype's template only")
    p.add_argument("--renders", type=Path, help="also judge these given frontal renders (<id>.png, _mask.png, .json), e.g. the shared renders")
    p.add_argument("--labels", type=Path, help="CSV of true subtypes (id,family,subtype) to score the subtype picked on accepted 0 deg views, e.g. docs/shared_subtypes.csv; --synth samples carry their own")
    p.add_argument("--angles", default="0,10,30,45,60,90", help="turns in degrees, comma-separated (default: 0,10,30,45,60,90)")
    p.add_argument("--resolution", type=int, default=256, help="side of the rendered views (default: 256)")
    p.add_argument("--limit", type=int, help="only the first N meshes")
    _add_set_option(p, "turned_margin=1")
    p.add_argument("-o", "--out", type=Path, default=Path("frontal3d-gate"), help="output folder (default: ./frontal3d-gate)")
    p.add_argument("-v", "--verbose", action="store_true", help="with --meshes, also picture the views judged the wrong way "
                   "(turned ones accepted, front ones turned down) in OUT/misjudged.png")
    p.set_defaults(run=_cmd_evaluate_gate)

    p = sub.add_parser("evaluate-regions", help="measure the inner-region segmentation on synthetic samples", description="Reconstruct each frontal sample of a `frontal3d synth` folder with its true mask and subtype, and compare the region map on the working grid with the sample's true one: mean IoU per sample and per region (pooled), for the aligned template's transferred map and for the pipeline's refined map (the learned region model's, with --set 'weights={regions=\"CKPT\"}'). Writes OUT/regions.csv and OUT/summary.txt.")
    p.add_argument("--family", required=True)
    p.add_argument("--synth", type=Path, required=True, help="a `frontal3d synth` folder (its regions/ hold the true maps)")
    p.add_argument("--limit", type=int, help="only the first N frontal samples")
    _add_set_option(p, "'weights={regions=\"regions.pt\"}'")
    p.add_argument("-o", "--out", type=Path, default=Path("frontal3d-regions"), help="output folder (default: ./frontal3d-regions)")
    p.set_defaults(run=_cmd_evaluate_regions)

    p = sub.add_parser("bench", help="time each stage and measure peak memory", description="Reconstruct an image several times and print per-stage seconds and peak memory.")
    p.add_argument("image", type=Path, nargs="?", help="input photo (default: the bundled example)")
    p.add_argument("--family", default="auto")
    p.add_argument("--mask", type=Path)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--json", action="store_true")
    p.set_defaults(run=_cmd_bench)

    p = sub.add_parser("synth", help="render synthetic training photos from a family's templates", description="Render randomized photos of each subtype's template (perturbed shape, frontal or turned view, random colours, textures, light and background). Writes DIR/images, DIR/masks, DIR/regions (*.png) and DIR/labels.csv (file, family, subtype, frontal, yaw, pitch); the same seed gives the same data.")
    p.add_argument("--family", required=True)
    p.add_argument("-n", "--count", type=int, required=True, help="number of samples")
    p.add_argument("-o", "--out", type=Path, required=True, help="output folder")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--resolution", type=int, default=256, help="side of the square images (default: 256)")
    p.add_argument("--grain", type=float, default=0.0, help="share of backgrounds (0-1) that also get fine grain, as paper or fabric shows (default: 0)")
    p.add_argument("--clutter", type=float, default=0.0, help="share of samples (0-1) with blobs behind the object touching its outline, half in its own colours (default: 0)")
    p.add_argument("--people", type=float, default=0.0, help="share of samples (0-1) with a drawn person: a player behind the object with arms across it, or someone in front of part of it (cut from the mask) (default: 0)")
    p.set_defaults(run=_cmd_synth)

    p = sub.add_parser("train", help="train a learned model (frontal gate, subtype, object segmenter, regions) on `synth` data", description="Train on a `frontal3d synth` folder (CPU), print the held-out score after each epoch and write a checkpoint. frontal, subtype: a small CNN, or ResNet-18 with --arch resnet18, on the masked object crop (held-out accuracy). segmenter: a small U-Net from the whole photo to the object's mask; regions: the same network from the object crop to the family's regions (held-out IoU). Use a checkpoint with the family setting weights = {TASK = \"CKPT\"}.")
    p.add_argument("task", choices=["frontal", "subtype", "segmenter", "regions"])
    p.add_argument("--data", type=Path, required=True, nargs="+", metavar="DIR",
                   help="folder written by `frontal3d synth`; the segmenter takes several, of any families (the checkpoint is the first one's family's)")
    p.add_argument("-o", "--out", type=Path, required=True, help="checkpoint to write (.pt)")
    p.add_argument("--epochs", type=int, default=8)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--size", type=int, default=None, help="side of the square the segmenter or region network sees, a multiple of 8 (default: 96; the checkpoint keeps it)")
    p.add_argument("--arch", choices=["compact", "resnet18"], default="compact",
                   help="frontal and subtype: compact (a 0.3 M-parameter ResNet, 1.2 MB) or resnet18 (torchvision's ResNet-18 layout, 11 M parameters, 45 MB, about 7x slower to train) (default: compact)")
    p.set_defaults(run=_cmd_train, out_is_file=True)
    return parser


def _plugins(args: argparse.Namespace) -> Plugins:
    plugins = Plugins(load_config(find_config_path(args.config)))
    for info in plugins.broken:
        print(f"frontal3d: warning: plugin {info.name} not loaded: {info.error}", file=sys.stderr)
    return plugins


def _parse_sets(pairs: list[str]) -> dict[str, Any]:
    import tomllib

    settings = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or not key:
            raise ConfigError(f"--set {pair!r}: expected KEY=VALUE")
        try:
            settings[key] = tomllib.loads(f"v = {value}")["v"]
        except tomllib.TOMLDecodeError:
            settings[key] = value
    return settings


def _cmd_reconstruct(args: argparse.Namespace) -> int:
    from frontal3d.pipeline import reconstruct, reconstruct_all
    from frontal3d.progress import StageProgress

    if len(args.images) > 1 and (args.mask or args.occluder_mask):
        raise ConfigError("--mask and --occluder-mask need a single IMAGE")
    plugins = _plugins(args)
    settings = _parse_sets(args.set)
    failures = 0
    with StageProgress(len(args.images)) as progress:
        for image in args.images:
            progress.start(image.name)
            try:
                arguments = dict(mask=args.mask, occluder_mask=args.occluder_mask, subtype=args.subtype, plugins=plugins, progress=progress.stage, **settings)
                if args.all:
                    results = reconstruct_all(image, args.family, **arguments)
                    folders = [args.out / f"{image.stem}_{k}" for k in range(1, len(results) + 1)]
                else:
                    results, folders = [reconstruct(image, args.family, **arguments)], [args.out / image.stem]
                saved = [(result.report, result.save(folder, debug=args.verbose)) for result, folder in zip(results, folders)]
            except Frontal3DError as exc:
                if isinstance(exc, NotFrontalError) and args.verbose and exc.outlines:
                    exc = _pictured(exc, image, args.out)
                if len(args.images) == 1:
                    raise exc
                failures += 1
                named = str(image) in str(exc)  # most messages name the file already
                progress.write(f"frontal3d: error: {exc}" if named else f"frontal3d: error: {image}: {exc}")
                continue
            for report, paths in saved:
                progress.write(f"{image}: {report['family']}/{report['subtype']} -> {paths['glb']} ({report['mesh']['faces']} faces, {report['seconds_total']:.1f} s)")
                for warning in report["warnings"]:
                    progress.write(f"  warning: {warning}")
    return 2 if failures else 0


def _pictured(error: NotFrontalError, image: Path, out: Path) -> NotFrontalError:
    """``error`` naming a sheet of the outlines it judged, written whole to OUTDIR/<stem>_turned_down.png."""
    import os

    from PIL import Image

    from frontal3d.imageio import read_image
    from frontal3d.preview import outline_sheet

    target = out / f"{image.stem}_turned_down.png"
    out.mkdir(parents=True, exist_ok=True)
    staging = target.with_name(f".{target.name}.partial")
    Image.fromarray(outline_sheet(read_image(image)[..., :3], error.outlines)).save(staging, format="PNG")
    os.replace(staging, target)
    return NotFrontalError(f"{error}; the outline judged: {target}", error.outlines)


def _cmd_families(args: argparse.Namespace) -> int:
    from frontal3d.catalogue import family_catalogue

    plugins = _plugins(args)
    catalogue = family_catalogue(plugins)
    if args.json:
        print(json.dumps(catalogue, indent=2))
        return 0
    for fam in catalogue:
        print(f"{fam['name']} ({fam['canonical_view']} view): {fam['description']}")
        for sub in fam["subtypes"]:
            regions = ", ".join(fam["regions"][sub])
            landmarks = ", ".join(fam.get("landmarks", {}).get(sub, []))
            print(f"  {sub}: regions {regions}" + (f"; landmarks {landmarks}" if landmarks else ""))
    return 0


def _cmd_plugins(args: argparse.Namespace) -> int:
    plugins = _plugins(args)
    infos = [info.to_dict() for info in plugins.infos]
    if args.json:
        print(json.dumps(infos, indent=2))
        return 0
    for info in infos:
        version = f" {info['version']}" if info["version"] else ""
        print(f"{info['name']}{version} [{info['source']}]")
        if info["error"]:
            print(f"  ERROR: {info['error']}")
        else:
            print(f"  hooks: {', '.join(info['hooks'])}")
    return 0


def _cmd_new_family(args: argparse.Namespace) -> int:
    from frontal3d.scaffold import scaffold_family

    out = scaffold_family(args.name, args.out or Path(f"frontal3d-{args.name}"), view=args.view, template_mesh=args.template)
    print(f"created {out}")
    print(f"next: pip install -e {out} && frontal3d families")
    return 0


def _cmd_template_build(args: argparse.Namespace) -> int:
    import yaml

    from frontal3d.render import load_or_render
    from frontal3d.template_tools import contact_sheet, template_from_mesh

    plugins = _plugins(args)
    family = plugins.family(args.family)
    regions = yaml.safe_load(args.regions.read_text()) if args.regions else None
    template, warnings = template_from_mesh(args.mesh, family, args.subtype, regions)
    for warning in warnings:
        print(f"warning: {warning}", file=sys.stderr)
    settings = plugins.settings(family.name)
    renders = load_or_render(template, int(settings["template_resolution"]), cache_dir=plugins.config.cache_dir)
    print(f"template {family.name}/{args.subtype}: {len(template.mesh.faces)} faces, regions {', '.join(template.region_names)}; renders cached ({renders.resolution}px)")
    print(f"use it with: [families.{family.name}] template_path = \"{args.mesh.resolve()}\" in plugins.toml")
    if args.out:
        contact_sheet(template, renders, args.out)
        print(f"wrote {args.out}")
    return 0


def _cmd_template_show(args: argparse.Namespace) -> int:
    from frontal3d.render import load_or_render
    from frontal3d.template_tools import contact_sheet

    plugins = _plugins(args)
    family_name, _, subtype = args.which.partition("/")
    family = plugins.family(family_name)
    settings = plugins.settings(family.name)
    template = plugins.hook.frontal3d_template(family=family, subtype=subtype or family.subtypes[0], settings=settings)
    renders = load_or_render(template, int(settings["template_resolution"]), cache_dir=plugins.config.cache_dir)
    contact_sheet(template, renders, args.out)
    print(f"wrote {args.out}")
    return 0


def _cmd_evaluate(args: argparse.Namespace) -> int:
    from frontal3d.baseline import SLAB_THICKNESS_RATIO, slab_reconstructor
    from frontal3d.evaluate import pipeline_reconstructor, run_evaluation, summary_lines

    plugins = _plugins(args)
    plugins.family(args.family)
    if args.method == "slab":
        reconstructor = slab_reconstructor(SLAB_THICKNESS_RATIO.get(args.family, 0.1))
    else:
        reconstructor = pipeline_reconstructor(plugins, args.family, **_parse_sets(args.set))
    rows = run_evaluation(args.family, args.meshes, args.renders, reconstructor, args.out, limit=args.limit, progress=sys.stderr.isatty(),
                          sheets=args.verbose)
    print("\n".join(summary_lines(rows)))
    print(f"wrote {args.out}/metrics.csv, summary.csv, boxplots.png" + (f" and a sheet per mesh in {args.out}/sheets" if args.verbose else ""))
    return 0


def _cmd_evaluate_occlusion(args: argparse.Namespace) -> int:
    from frontal3d.eval_occlusion import run_occlusion_evaluation, summarize, summary_lines

    plugins = _plugins(args)
    plugins.family(args.family)
    if args.per_object < 1:
        raise ConfigError("--per-object must be at least 1")
    rows = run_occlusion_evaluation(args.family, args.meshes, args.renders, args.occluders, plugins, args.out, seed=args.seed,
                                    per_object=args.per_object, limit=args.limit, settings=_parse_sets(args.set), progress=sys.stderr.isatty(),
                                    every=args.every, offset=args.offset, segment=args.segment)
    print("\n".join(summary_lines(summarize(rows))))
    print(f"wrote {args.out}/composites.csv, summary.csv, images/")
    return 0


def _cmd_evaluate_masks(args: argparse.Namespace) -> int:
    from frontal3d.eval_masks import BACKGROUNDS, evaluate_masks, render_paths, summary_lines
    from frontal3d.progress import counter

    backgrounds = [b.strip() for b in args.backgrounds.split(",") if b.strip()] if args.backgrounds else list(BACKGROUNDS)
    total = len(render_paths(args.renders, args.every, args.offset)) * len(backgrounds)
    with counter(total, "image") as bar:
        scores = evaluate_masks(_plugins(args), args.family, args.renders, args.out, backgrounds, every=args.every, offset=args.offset,
                                seed=args.seed, debug=args.verbose, settings=_parse_sets(args.set), progress=bar.update)
    print("\n".join(summary_lines(scores)))
    print(f"wrote {args.out}/masks.csv, summary.csv" + (f" and debug sheets in {args.out}/debug" if args.verbose else ""))
    return 0


def _cmd_evaluate_gate(args: argparse.Namespace) -> int:
    from frontal3d.eval_gate import evaluate_gate, evaluate_gate_on_synth, read_subtype_labels
    from frontal3d.progress import counter

    try:
        angles = [float(a) for a in args.angles.split(",") if a.strip()]
    except ValueError:
        raise ConfigError(f"--angles {args.angles!r}: expected degrees separated by commas, e.g. 0,10,30") from None
    if not angles or args.resolution < 64:
        raise ConfigError("evaluate-gate needs at least one angle and --resolution >= 64")
    plugins = _plugins(args)
    if args.synth is not None:
        with counter(None, "sample") as bar:
            _, summary = evaluate_gate_on_synth(plugins, args.family, args.synth, args.out, args.limit, _parse_sets(args.set),
                                                args.subtype, progress=bar.update)
        print("\n".join(summary.lines()))
        print(f"wrote {args.out}/gate.csv, summary.txt")
        return 0
    labels = read_subtype_labels(args.labels, plugins.family(args.family)) if args.labels else None
    meshes = len(sorted(args.meshes.glob("*.glb"))[: args.limit])
    with counter(meshes, "mesh") as bar:
        _, summary = evaluate_gate(plugins, args.family, args.meshes, args.out, angles, args.resolution, args.limit,
                                   _parse_sets(args.set), args.renders, args.subtype, progress=bar.update, labels=labels,
                                   sheet=args.verbose)
    print("\n".join(summary.lines()))
    print(f"wrote {args.out}/gate.csv, summary.txt" + (", misjudged.png" if args.verbose else ""))
    return 0


def _cmd_evaluate_regions(args: argparse.Namespace) -> int:
    from frontal3d.eval_regions import evaluate_regions_on_synth
    from frontal3d.progress import counter

    plugins = _plugins(args)
    with counter(args.limit, "sample") as bar:
        _, summary = evaluate_regions_on_synth(plugins, args.family, args.synth, args.out, args.limit, _parse_sets(args.set), progress=bar.update)
    print("\n".join(summary.lines()))
    print(f"wrote {args.out}/regions.csv, summary.txt")
    return 0


def _cmd_bench(args: argparse.Namespace) -> int:
    from frontal3d.bench import run_bench

    plugins = _plugins(args)
    return run_bench(plugins, args.image, args.family, args.mask, args.repeat, as_json=args.json)


def _cmd_synth(args: argparse.Namespace) -> int:
    from frontal3d.progress import counter
    from frontal3d.synth import synthesize

    if args.count < 1 or args.resolution < 32 or not all(0 <= share <= 1 for share in (args.grain, args.clutter, args.people)):
        raise ConfigError("synth needs -n >= 1, --resolution >= 32 and --grain, --clutter and --people between 0 and 1")
    plugins = _plugins(args)
    family = plugins.family(args.family)
    settings = plugins.settings(family.name)
    templates = {s: plugins.hook.frontal3d_template(family=family, subtype=s, settings=settings) for s in family.subtypes}
    with counter(args.count, "image") as bar:
        labels = synthesize(family, templates, args.count, args.out, seed=args.seed, resolution=args.resolution, progress=bar.update, grain=args.grain, clutter=args.clutter, people=args.people)
    print(f"wrote {args.count} samples of {family.name} ({', '.join(templates)}) to {args.out}; labels in {labels}")
    return 0


def _cmd_train(args: argparse.Namespace) -> int:
    from frontal3d.learned import CLASSIFIER_ARCHITECTURES, DENSE_TASKS
    from frontal3d.learned_dense import DENSE_INPUT_SIZE
    from frontal3d.train import load_dataset, load_dense_dataset, single_folder, train

    if args.epochs < 1:
        raise ConfigError("--epochs must be at least 1")
    if args.size is not None and (args.task not in DENSE_TASKS or args.size < 32 or args.size % 8):
        raise ConfigError("--size is for the segmenter and regions tasks: a multiple of 8, at least 32")
    if args.arch != "compact" and args.task in DENSE_TASKS:
        raise ConfigError("--arch is for the frontal and subtype classifiers (the segmenter and regions tasks have one network)")
    if args.task in DENSE_TASKS:
        dataset = load_dense_dataset(args.data, args.task, _plugins(args).family, size=args.size or DENSE_INPUT_SIZE)
        what = "object segmenter" if args.task == "segmenter" else "region model"
    else:
        dataset = load_dataset(single_folder(args.data, args.task), args.task)
        what = f"{args.task} classifier"
    print(f"{what} for {dataset.family}: {len(dataset.targets)} samples, classes {', '.join(dataset.classes)}")
    result = train(dataset, args.task, args.out, epochs=args.epochs, seed=args.seed, architecture=CLASSIFIER_ARCHITECTURES[args.arch])
    print(f"wrote {args.out} (held-out {result.metric} {result.held_out_accuracy[-1]:.3f} on {result.held_out_count} samples)")
    print(f"use it with: [families.{dataset.family}] weights = {{{args.task} = \"{args.out.resolve()}\"}} in plugins.toml")
    return 0


if __name__ == "__main__":
    sys.exit(main())
