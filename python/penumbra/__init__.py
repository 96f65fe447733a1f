"""penumbra: out-of-core soft-shadow baking, driven from Python.

Scenes come from JSON files, dicts with the same keys, built-in generators and Python triangle
sources (NumPy chunks); bake() runs the same pipeline as the `penumbra bake` command and returns
NumPy arrays; Result.write() writes the command's outputs byte for byte.
"""


def _check_address_space():
    """Refuses the import, with a sentence, where an address-space limit cannot hold the module.

    Loading the compiled module maps its libraries (OpenVDB and its logging library, which starts
    a thread as it loads); under a limit that leaves room for the libraries but not for that
    thread's stack, the thread's failure aborted the interpreter (SIGABRT) from inside the loader.
    """
    import resource
    limit, _ = resource.getrlimit(resource.RLIMIT_AS)
    if limit == resource.RLIM_INFINITY:
        return
    try:
        with open("/proc/self/status") as status:
            mapped = next(int(line.split()[1]) * 1024 for line in status if line.startswith("VmSize:"))
    except (OSError, StopIteration, ValueError, IndexError):
        return
    needed = mapped + _IMPORT_ADDRESS_SPACE
    if needed > limit:
        raise ImportError(
            f"penumbra: the address-space limit (prlimit --as, ulimit -v) of {limit >> 20} MiB is too small to load the "
            f"module: this process has {mapped >> 20} MiB mapped, and loading needs about {_IMPORT_ADDRESS_SPACE >> 20} MiB "
            f"more (at least {-(-needed // (1 << 20))}M); a bake needs more again")


# What `import penumbra` adds to the address space (measured on Debian 12: 146 MiB for the
# libraries, the logging thread's stack and its malloc arena), with a little to spare.
_IMPORT_ADDRESS_SPACE = 152 << 20
_check_address_space()

from ._penumbra import (Error, Result, Scene, SceneError, bake, generate, methods)  # noqa: E402

__all__ = ["Error", "Result", "Scene", "SceneError", "bake", "generate", "methods"]
