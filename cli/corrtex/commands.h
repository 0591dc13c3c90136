/* commands.h: the subcommands of bin/corrtex (the offline tools). Each takes
 * the arguments after its name (argv[0] is the subcommand name) and returns
 * the process exit status: 0 ok, 1 a check failed (e.g. --max-rmse), 2 bad
 * input or usage. */
#ifndef CT_CLI_COMMANDS_H
#define CT_CLI_COMMANDS_H

typedef struct cli_command {
    const char *name;
    const char *summary;
    int (*run)(int argc, char **argv);
} cli_command;

/* corrtex info: scene counts and bounds. */
int cmd_info(int argc, char **argv);

/* corrtex radiosity: hierarchical radiosity into a .ctmesh cache. */
int cmd_radiosity(int argc, char **argv);

/* corrtex reference: the offline high-quality renderer (cmd_reference.c). */
int cmd_reference(int argc, char **argv);

/* The table, terminated by a NULL name (main.c). */
extern const cli_command cli_commands[];

/* corrtex compare A.exr B.exr [--json] [--max-rmse X] (cmd_compare.c). */
int cmd_compare(int argc, char **argv);

/* corrtex converge SCENE --samples N[,N2,...] --out DIR [options] (cmd_converge.c):
 * the master engine and the tracer in one process (docs/textures.md). */
int cmd_converge(int argc, char **argv);

/* corrtex naive SCENE --mesh M --path P -o DIR: radiosity alone and the naive
 * point display, the walkthrough benchmark's baselines (cmd_naive.c). */
int cmd_naive(int argc, char **argv);

/* corrtex montage -o SHEET.png IMAGE... (cmd_montage.c). */
int cmd_montage(int argc, char **argv);


#endif
