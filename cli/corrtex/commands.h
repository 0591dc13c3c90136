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

/* corrtex reference: the offline high-quality renderer (cmd_reference.c). */
int cmd_reference(int argc, char **argv);

/* The table, terminated by a NULL name (main.c). */
extern const cli_command cli_commands[];

/* corrtex compare A.exr B.exr [--json] [--max-rmse X] (cmd_compare.c). */
int cmd_compare(int argc, char **argv);

/* corrtex montage -o SHEET.png IMAGE... (cmd_montage.c). */
int cmd_montage(int argc, char **argv);

#endif
