"""The compiled model: :class:`Model` (a robot's CasADi functions compiled to C, NumPy in
and out), the compiler and the on-disk cache, code over lanes, and C export."""

from softcurve.compiled._build import CompilerWarning as CompilerWarning
from softcurve.compiled._cache import CacheWarning as CacheWarning
from softcurve.compiled._declarations import read_header as read_header
from softcurve.compiled._export import ExportedC as ExportedC
from softcurve.compiled._export import build_and_run_test as build_and_run_test
from softcurve.compiled._export import c_identifier as c_identifier
from softcurve.compiled._export import export_c as export_c
from softcurve.compiled._generated import compile_function as compile_function
from softcurve.compiled._generated import compile_functions as compile_functions
from softcurve.compiled._lanes import LANE_WIDTH as LANE_WIDTH
from softcurve.compiled._lanes import c_template as c_template
from softcurve.compiled._lanes import compile_lanes as compile_lanes
from softcurve.compiled._lanes import lanes_function as lanes_function
from softcurve.compiled._lanes import lanes_prelude as lanes_prelude
from softcurve.compiled._lanes import lanes_work as lanes_work
from softcurve.compiled._model import DynamicsTerms as DynamicsTerms
from softcurve.compiled._model import Model as Model
from softcurve.compiled._model import Pose as Pose
from softcurve.compiled._native import NativeFunction as NativeFunction
from softcurve.compiled._source import compile_files as compile_files
from softcurve.compiled._source import compile_source as compile_source
from softcurve.compiled._source import exact_external as exact_external
from softcurve.compiled._source import load_external as load_external
from softcurve.compiled._source import load_function as load_function
from softcurve.compiled._source import load_library as load_library
from softcurve.compiled._source import load_with_path as load_with_path

__all__ = [
    "CompilerWarning",
    "CacheWarning",
    "ExportedC",
    "build_and_run_test",
    "c_identifier",
    "export_c",
    "compile_function",
    "compile_functions",
    "exact_external",
    "load_external",
    "LANE_WIDTH",
    "compile_lanes",
    "lanes_function",
    "lanes_prelude",
    "lanes_work",
    "DynamicsTerms",
    "Model",
    "Pose",
    "NativeFunction",
    "compile_source",
    "read_header",
    "c_template",
    "compile_files",
    "load_function",
    "load_library",
    "load_with_path",
]
