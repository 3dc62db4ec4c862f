!> The global structured grid: a rectangle of nx by ny cells, its node and cell numbering.
module iem_grid
  use iem_kinds, only: wp, i8
  implicit none
  private
  public :: grid_t

  !> Global grid; node (i, j) has 0-based index i + j*(nx+1), cell (i, j) has i + j*nx.
  type :: grid_t
    integer :: nx = 0, ny = 0
    real(wp) :: lx = 0.0_wp, ly = 0.0_wp, thickness = 1.0_wp
    integer(i8) :: n_nodes = 0, n_cells = 0
  contains
    procedure :: init => grid_init
    procedure :: node_id => grid_node_id
    procedure :: node_ij => grid_node_ij
    procedure :: node_xy => grid_node_xy
    procedure :: cell_corners => grid_cell_corners
    procedure :: nearest_node => grid_nearest_node
    procedure :: label => grid_label
  end type grid_t

contains

  !> Set up the grid for a rectangle length x height with nx x ny cells.
  subroutine grid_init(this, length, height, thickness, nx, ny)
    class(grid_t), intent(out) :: this
    real(wp), intent(in) :: length, height, thickness
    integer, intent(in) :: nx, ny
    this%nx = nx
    this%ny = ny
    this%lx = length/nx
    this%ly = height/ny
    this%thickness = thickness
    this%n_nodes = (int(nx, i8) + 1)*(int(ny, i8) + 1)
    this%n_cells = int(nx, i8)*int(ny, i8)
  end subroutine grid_init

  !> The input that sets the grid, for messages: '&geometry: nx, ny = 40000, 40000'.
  pure function grid_label(this) result(s)
    class(grid_t), intent(in) :: this
    character(len=:), allocatable :: s
    character(len=40) :: b
    write(b, '(i0,a,i0)') this%nx, ', ', this%ny
    s = '&geometry: nx, ny = '//trim(b)
  end function grid_label

  !> 0-based global index of node (i, j).
  elemental integer(i8) function grid_node_id(this, i, j) result(g)
    class(grid_t), intent(in) :: this
    integer, intent(in) :: i, j
    g = int(i, i8) + int(j, i8)*int(this%nx + 1, i8)
  end function grid_node_id

  !> Grid indices (i, j) of the 0-based global node g.
  pure function grid_node_ij(this, g) result(ij)
    class(grid_t), intent(in) :: this
    integer(i8), intent(in) :: g
    integer :: ij(2)
    ij(1) = int(mod(g, int(this%nx + 1, i8)))
    ij(2) = int(g/int(this%nx + 1, i8))
  end function grid_node_ij

  !> Initial coordinates of the 0-based global node g.
  pure function grid_node_xy(this, g) result(xy)
    class(grid_t), intent(in) :: this
    integer(i8), intent(in) :: g
    real(wp) :: xy(2)
    integer :: ij(2)
    ij = this%node_ij(g)
    xy = [ij(1)*this%lx, ij(2)*this%ly]
  end function grid_node_xy

  !> Corner node indices (0-based, counter-clockwise from lower left) of the 0-based cell c.
  pure function grid_cell_corners(this, c) result(nodes)
    class(grid_t), intent(in) :: this
    integer(i8), intent(in) :: c
    integer(i8) :: nodes(4)
    integer :: i, j
    i = int(mod(c, int(this%nx, i8)))
    j = int(c/int(this%nx, i8))
    nodes(1) = this%node_id(i, j)
    nodes(2) = this%node_id(i + 1, j)
    nodes(3) = this%node_id(i + 1, j + 1)
    nodes(4) = this%node_id(i, j + 1)
  end function grid_cell_corners

  !> The node nearest to (x, y) (points outside are clamped to the rectangle).
  pure integer(i8) function grid_nearest_node(this, x, y) result(g)
    class(grid_t), intent(in) :: this
    real(wp), intent(in) :: x, y
    integer :: i, j
    i = min(max(nint(x/this%lx), 0), this%nx)
    j = min(max(nint(y/this%ly), 0), this%ny)
    g = this%node_id(i, j)
  end function grid_nearest_node
end module iem_grid
