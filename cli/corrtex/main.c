/* bin/corrtex: the offline tools as subcommands. A thin dispatcher: every
 * subcommand parses its own options and calls into the libraries. */
#include <stdio.h>
#include <string.h>

#include "cli/corrtex/commands.h"
#include "common/version.h"

const cli_command cli_commands[] = {
    {"info", "counts and bounds of a scene (--json for machines)", cmd_info},
    {"radiosity", "hierarchical radiosity solution as a .ctmesh cache", cmd_radiosity},
    {"compare", "image error metrics of A.exr against reference B.exr", cmd_compare},
    {"reference", "render the high-quality reference image(s) (path, drt, reuse-diffuse)", cmd_reference},
    {"converge", "corrective textures converging for a still camera (master + tracer, one process)", cmd_converge},
    {"naive", "walkthrough baselines: radiosity alone, naive point display of samples", cmd_naive},
    {"montage", "contact sheet PNG of walkthrough frames (PNG or EXR)", cmd_montage},
    {NULL, NULL, NULL}
};

static void usage(FILE *f)
{
    fprintf(f, "usage: corrtex COMMAND [options]   (corrtex COMMAND --help for its options)\n"
               "       corrtex --version            (the version and the git commit it was built from)\n\n"
               "commands:\n");
    for (const cli_command *c = cli_commands; c->name; c++)
        fprintf(f, "  %-12s %s\n", c->name, c->summary);
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        /* Bad usage is one line everywhere (README.md); the list is --help's. */
        fputs("error corrtex: missing COMMAND (", stderr);
        for (const cli_command *c = cli_commands; c->name; c++) fprintf(stderr, "%s%s", c->name, c[1].name ? ", " : "");
        fputs("; try corrtex --help)\n", stderr);
        return 2;
    }
    if (strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0 || strcmp(argv[1], "help") == 0) {
        usage(stdout);
        return 0;
    }
    if (strcmp(argv[1], "--version") == 0) {
        ct_version_print("corrtex", stdout);
        return 0;
    }
    for (const cli_command *c = cli_commands; c->name; c++)
        if (strcmp(argv[1], c->name) == 0) return c->run(argc - 1, argv + 1);
    fprintf(stderr, "error corrtex: unknown command '%s' (try corrtex --help)\n", argv[1]);
    return 2;
}
