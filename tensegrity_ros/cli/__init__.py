"""``tensegrity``: the offline command line of tensegrity_ros (docs/cli.md).

Subcommands::

    tensegrity solve   --rho R [params] [--json]
    tensegrity solve   --modules N --rho R | --rhos R0 .. RN-1 [params] [--json]   (neck stack)
    tensegrity solve   --config FILE.yaml [params] [--json]                         (neck stack)
    tensegrity track   --rho R0 --to-rho R1 [--to-F3 ...] [--theta1 T1 --theta2 T2] [--json]
    tensegrity track   --modules N | --config FILE ... --to-rhos .. [--theta T ..] [--json]
    tensegrity map     --x NAME MIN MAX COUNT --y NAME MIN MAX COUNT [params] [--csv F] [--png F]
                       [--boundaries] [--boundaries-csv F]
    tensegrity diagram --from-rho A --to-rho B [--count N] [params] --png F [--csv F]
                       [--track R0 R1 ...]
    tensegrity range   --rho R [--theta1 T1 --theta2 T2] [params] [--json]
    tensegrity limit   --L2 X [--pushing] [--json]
    tensegrity snap    --rho R0 --to-rho R1 --rate V --damping C --m1 M --m2 M [...]  (dynamics)

Units are SI (m, N, N/m, kg); angles are radians on input and in JSON/CSV, the
human-readable tables show degrees.  The paper's F3, F4 are the vertical force
components (positive pulls up).  ``--k`` sets all three springs, ``--ka/--kb/--kc``
override it; ``--F`` sets F3 = F4, ``--F3/--F4`` override it.

Stack (several modules, docs/model.md section 4): geometry, stiffness and mass options
apply to every module, ``--rho`` to every module (``--rhos`` one per module), the
force options to the top module (the head).  ``--config`` reads a node parameter
file; options given with it override the file in the same way.

Bad arguments give a one-line message on stderr and exit status 2.  The package
does not import rclpy (nor matplotlib unless a PNG is requested).

One module per command (``solve``, ``track``, ``map``, ``diagram``, ``range``,
``limit``, ``snap``, ``tolerance``): each registers its subparser (``add_parser``)
and runs it (``run``); :mod:`.app` assembles the parser and runs a command line,
:mod:`.common` and :mod:`.records` hold what the commands share.
"""
from .app import build_parser, main
from .common import EXIT_FAILURE, EXIT_OK, EXIT_USAGE, UsageError

__all__ = ['EXIT_FAILURE', 'EXIT_OK', 'EXIT_USAGE', 'UsageError', 'build_parser', 'main']
