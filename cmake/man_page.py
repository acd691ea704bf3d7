#!/usr/bin/env python3
"""Writes occmap(1) from the program's own --help texts, so the manual cannot drift from the CLI.

Usage: man_page.py OCCMAP_PROGRAM VERSION OUT.1.gz

The top-level --help gives the global options and the commands; each command's --help its
positionals and options (CLI11's layout: "Positionals:", "Options:", "Subcommands:" sections of
"  NAME   description" entries, a long NAME pushing its description to the next line). The hand-
written sections (description, exit status, environment, files, examples) follow the README.
The page is gzipped without a time stamp (gzip -n), as Debian installs manual pages.
"""
import gzip
import re
import subprocess
import sys

DESCRIPTION = """\
occmap turns several fixed, calibrated cameras into a map of what occupies a floor
(volume intersection in a plane). Every pixel of every camera is cast once, off-line, to the
floor plane (the lookup tables, cached); on-line a floor cell is free as soon as one pixel that
views it sees no change against the background, and occupied only if all of them do. From the
maps come detections, tracks, zone events and line crossings, written as JSON lines, pictures
and videos, and optionally published on MQTT or served to a browser.
.PP
A site file (YAML) names the cameras, their calibrations, frame sources, masks and the floor
grid; relative paths in it resolve against its folder, or against its data_root or
\\fB\\-\\-data\\-root\\fR. Every file format is described in formats.md (see FILES)."""

EXIT_STATUS = """\
.TP
.B 0
success (also after a first SIGINT or SIGTERM, which stops a run after the frame sets in flight
with every output closed)
.TP
.B 1
other failures, e.g. an output that cannot be written
.TP
.B 2
bad input: a file, an option or its content; the message names the file, the line, the field,
what was expected and what was found
.TP
.B 128+N
a second signal N during \\fBrun\\fR or \\fBserve\\fR: temporary files removed, the outputs valid up
to their last whole line"""

ENVIRONMENT = """\
.TP
.B XDG_CACHE_HOME\\fR, \\fBHOME
the default cache of tables and backgrounds is \\fI$XDG_CACHE_HOME/occmap\\fR, else
\\fI~/.cache/occmap\\fR (\\fB\\-\\-cache\\-dir\\fR, \\fB\\-\\-no\\-cache\\fR)
.TP
.B OCCMAP_KERNELS
\\fBportable\\fR, \\fBavx2\\fR or \\fBavx512\\fR: force one set of fast kernels (default: the best
the CPU has)"""

FILES = """\
.TP
.I /usr/share/occmap/sites/
example site files (lab, gopro4, wildtrack, ...)
.TP
.I /usr/share/doc/occmap/README.md
the guide: live operation, calibration, real scenes, Python, use from C++
.TP
.I /usr/share/doc/occmap/formats.md
every file occmap reads or writes"""

EXAMPLES = """\
Render the built-in lab scene, run on it and score the result:
.PP
.RS
.nf
occmap demo \\-\\-out demo\\-out
.fi
.RE
.PP
Check a site file, then run it without videos and score the run against a dataset's truth:
.PP
.RS
.nf
occmap check site.yaml
occmap run site.yaml \\-\\-out run \\-\\-no\\-video
occmap eval data run
.fi
.RE"""


def escape(text):
    """Troff text: backslashes, hyphens (so that options copy as typed) and leading dots."""
    text = text.replace("\\", "\\e").replace("-", "\\-")
    return "\\&" + text if text.startswith((".", "'")) else text


def help_of(program, args):
    result = subprocess.run([program, *args, "--help"], capture_output=True, text=True, check=True)
    return result.stdout


def parse(help_text):
    """CLI11's help: (summary line, usage line, {section: [(name, description)]})."""
    lines = help_text.splitlines()
    summary, usage, sections, section = "", "", {}, None
    for line in lines:
        if not line.strip():
            continue
        if line.startswith("Usage: "):
            usage = line[len("Usage: "):]
        elif re.fullmatch(r"[A-Z][A-Za-z ]*:", line):
            section = line[:-1]
            sections[section] = []
        elif section is None:
            summary = (summary + " " + line.strip()).strip()
        elif line.startswith(" " * 4) and sections[section]:
            name, description = sections[section][-1]
            sections[section][-1] = (name, (description + " " + line.strip()).strip())
        else:
            name, _, description = line.strip().partition("  ")
            sections[section].append((name.strip(), description.strip()))
    return summary, usage, sections


def option_entries(sections, skip_help=True):
    out = []
    for section in ("Positionals", "Options"):
        for name, description in sections.get(section, []):
            if skip_help and name.startswith("-h,--help"):
                continue
            flag, _, rest = name.partition(" ")
            out.append(f".TP\n\\fB{escape(flag)}\\fR{(' ' + escape(rest)) if rest else ''}\n"
                       f"{escape(description) or '(no description)'}")
    return out


def main():
    program, version, out_path = sys.argv[1:4]
    summary, _, top = parse(help_of(program, []))
    commands = top.get("Subcommands", [])
    if not commands:
        sys.exit(f"{program} --help lists no commands")
    page = [
        f'.TH OCCMAP 1 "" "occmap {version}" "occmap manual"',
        ".SH NAME",
        f"occmap \\- {escape(re.sub(r'^occmap: ', '', summary))}",
        ".SH SYNOPSIS",
        ".B occmap",
        "[\\fB\\-\\-threads\\fR \\fIN\\fR] [\\fB\\-\\-data\\-root\\fR \\fIDIR\\fR] \\fICOMMAND\\fR [\\fIOPTIONS\\fR]",
        ".br",
        ".B occmap",
        "\\fB\\-\\-help\\fR | \\fB\\-\\-version\\fR | \\fICOMMAND\\fR \\fB\\-\\-help\\fR",
        ".SH DESCRIPTION",
        DESCRIPTION,
        ".SH GLOBAL OPTIONS",
        *option_entries(top, skip_help=False),
        ".SH COMMANDS",
    ]
    for name, description in commands:
        page.append(".TP\n\\fB" + escape(name) + "\\fR\n" + escape(description))
    for name, _ in commands:
        summary, usage, sections = parse(help_of(program, [name]))
        usage = re.sub(r"^\S*occmap ", "occmap ", usage)
        page += [f".SS {escape(name)}", f"\\fB{escape(usage)}\\fR", ".PP", escape(summary) + "."]
        page += option_entries(sections)
    page += [".SH EXIT STATUS", EXIT_STATUS, ".SH ENVIRONMENT", ENVIRONMENT, ".SH FILES", FILES,
             ".SH EXAMPLES", EXAMPLES, ".SH SEE ALSO",
             "\\fBmosquitto_sub\\fR(1), \\fBffmpeg\\fR(1); the README and formats.md under FILES."]
    text = "\n".join(page) + "\n"
    with open(out_path, "wb") as raw, gzip.GzipFile(filename="", mode="wb", fileobj=raw, mtime=0,
                                                    compresslevel=9) as gz:
        gz.write(text.encode())


if __name__ == "__main__":
    main()
