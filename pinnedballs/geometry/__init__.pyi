# The room's names, each imported from its module when first used (`lazy_loader.attach_stub` reads this file; type
# checkers and the API page read it too).
from .base import VIEWS as VIEWS
from .base import Boundary as Boundary
from .base import Contacts as Contacts
from .base import Geometry as Geometry
from .graph import GraphGeometry as GraphGeometry
from .graph import StoredGeometry as StoredGeometry
from .hyperbolic import HyperbolicPlane as HyperbolicPlane
from .lattices import FlatTorus as FlatTorus
from .lattices import HalfPlane as HalfPlane
from .packings import FCC as FCC
from .packings import HCP as HCP
from .sphere import Sphere as Sphere
