"""``vtts say TEXT``: a talking head speaking bookmarked text."""

from __future__ import annotations

import argparse

from vtts.cli.options import add_curves, add_detail, add_models, add_view, add_web, seed_type
from vtts.messages import echo
from vtts.speech.engine import DEFAULT_ENGINE, ENGINES


def add_parser(sub) -> None:
    sy = sub.add_parser("say", help="speak text with bookmarks: a talking-head video")
    sy.add_argument(
        "text",
        nargs="?",
        default="",
        help='text with bookmarks, e.g. "Hello <smile 2s> world <blink>"',
    )
    sy.add_argument(
        "--text",
        dest="text_option",
        metavar="TEXT",
        help="the text, as an option (the same as giving it first; e.g. with --audio REC)",
    )
    sy.add_argument("--file", help="read the text from a file instead")
    add_models(sy)
    sy.add_argument(
        "--engine",
        choices=tuple(ENGINES),
        default=DEFAULT_ENGINE,
        help="speech synthesizer: espeak-ng (default), festival's HTS voice (Debian festival, "
        "festvox-us-slt-hts) or a Piper neural voice (the optional extra vtts[piper])",
    )
    sy.add_argument(
        "--voice",
        help="the engine's voice (vtts voices lists them): espeak-ng's default en-us, "
        "festival's cmu_us_slt_arctic_hts, Piper's first installed (en_US-joe-medium, or joe)",
    )
    sy.add_argument("--rate", type=int, help="speaking rate in words per minute")
    sy.add_argument("--pitch", type=int, help="pitch 0-99")
    sy.add_argument(
        "--phonemes",
        help="timings from another engine: Polly speech marks or a "
        "'start end phoneme' table (needs --audio)",
    )
    sy.add_argument(
        "--audio",
        help="recorded speech (WAV, FLAC, OGG, MP3, M4A …): the text is aligned to it; without "
        "a text its phones are recognized from the sound (US English); with --phonemes, the "
        "speech they describe",
    )
    sy.add_argument(
        "--words",
        choices=("auto", "always", "never"),  # vtts.speech.recognize.WORD_MODES, not imported
        default="auto",
        help="with --audio and no text: also recognize words (a language model) where the "
        "phones are uncertain, as in real speech (auto, the default), always, or never (faster)",
    )
    sy.add_argument("--seed", type=seed_type, default=0, help="seed of the autonomous behaviour")
    sy.add_argument(
        "--no-autonomous",
        action="store_true",
        help="no autonomous blinks, nods, head motion or gaze",
    )
    sy.add_argument("--fps", type=float, default=30.0, help="frame rate (default 30)")
    sy.add_argument("--fap-out", help="also write the FAP stream (.fap)")
    sy.add_argument("--wav-out", help="also write the speech (.wav)")
    sy.add_argument(
        "--timings-out",
        help="also write the word and phone timings (.tsv: kind start end label viseme)",
    )
    add_curves(sy)
    sy.add_argument("--png-dir", help="also (or only) write lossless PNG frames into this folder")
    sy.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    add_web(sy)
    add_view(sy)
    add_detail(sy)
    sy.add_argument("-o", "--output", help="output .mp4, or an animated .glb/.gltf")
    sy.set_defaults(func=cmd_say)


def cmd_say(args: argparse.Namespace) -> int:
    """Speak (:func:`vtts.api.say.say`) and say what was written."""
    from vtts.api.say import SayOptions, merged_text, say
    from vtts.cli.options import curves_options, view_options

    options = SayOptions(
        text=args.text,
        file=args.file,
        model=args.model,
        engine=args.engine,
        voice=args.voice,
        rate=args.rate,
        pitch=args.pitch,
        phonemes=args.phonemes,
        audio=args.audio,
        words=args.words,
        seed=args.seed,
        no_autonomous=args.no_autonomous,
        fps=args.fps,
        output=args.output,
        png_dir=args.png_dir,
        web=args.web,
        fap_out=args.fap_out,
        wav_out=args.wav_out,
        timings_out=args.timings_out,
        progress=not args.quiet,
        **curves_options(args),
        **view_options(args),
    )
    options.text = merged_text(args.text, args.text_option, args.file)
    said = say(options, on_first_frame=args.first_frame)
    if not args.quiet:
        echo(
            f"wrote {', '.join(said.written)}: {said.duration:.2f} s, {said.n_frames} frames "
            f"at {said.fps:g} fps"
        )
    return 0
