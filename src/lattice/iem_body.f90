!> The body: a background grid of rectangular cells, each cell void or of one material, from
!> the background material, an image cell map and shapes (later ones win; a cell takes what
!> holds its centre). Numbers the cells and nodes that exist (a node exists when a cell of the
!> body uses it) in row-major order of the grid, so a full rectangle keeps the grid's numbers.
!> Answers what a cell or node of the grid is, where a node lies, and which node is nearest.
module iem_body
  use, intrinsic :: iso_fortran_env, only: int8
  use iem_kinds, only: wp, i8
  use iem_grid, only: grid_t
  use iem_shapes, only: shape_t, shape_rectangle, shape_circle, shape_polygon, shape_contains
  use iem_config, only: config_t
  use iem_image, only: image_t, read_image
  use iem_strings, only: itoa, rtoa
  implicit none
  private
  public :: body_t, max_materials

  !> Most materials a body may have (a cell's material is kept in one byte).
  integer, parameter :: max_materials = 100

  !> The body cut from the background grid, with the numbering of its cells and nodes.
  type :: body_t
    type(grid_t) :: grid
    integer :: n_materials = 1
    !> Material of the grid before the image and the shapes (0: void).
    integer :: background = 1
    type(shape_t), allocatable :: shapes(:)
    !> True when every cell of the grid is of the background material (no image, no shape):
    !> cell and node numbers are then the grid's, and nothing is stored per cell.
    logical :: uniform = .true.
    !> Cells and nodes of the body.
    integer(i8) :: n_nodes = 0, n_cells = 0
    !> Not uniform: material (0: void) and deciding shape (0: background or image) of every
    !> grid cell; number of every grid cell and node in the body (-1: not in it), and the grid
    !> index of every cell and node of the body.
    integer(int8), allocatable :: cell_mat(:), cell_src(:)
    integer(i8), allocatable :: cell_id(:), node_id(:), cell_grid(:), node_grid(:)
    !> Cells of each material.
    integer(i8), allocatable :: material_cells(:)
    !> Pieces of the body (cells joined through shared nodes), and a cell of each of the
    !> smaller pieces (up to 5), for the log.
    integer :: n_pieces = 1
    integer(i8) :: piece_cell(5) = -1
  contains
    procedure :: init => body_init
    procedure :: material => body_material
    procedure :: source => body_source
    procedure :: cell_number => body_cell_number
    procedure :: node_number => body_node_number
    procedure :: node_ij => body_node_ij
    procedure :: cell_ij => body_cell_ij
    procedure :: node_xy => body_node_xy
    procedure :: nearest_node => body_nearest_node
    procedure :: cell_at => body_cell_at
    procedure :: cell_corners => body_cell_corners
    procedure :: free => body_free
  end type body_t

contains

  !> Build the body of the configuration on the grid: the cells' materials, the numbering, the
  !> pieces; stat /= 0 with msg (naming the group and variable) for an empty body, a shape that
  !> holds no cell centre, a material no cell uses, an unreadable or unmatched image, or more
  !> memory than there is. Every rank builds the same body.
  subroutine body_init(this, cfg, grid, stat, msg)
    class(body_t), intent(inout) :: this
    type(config_t), intent(in) :: cfg
    type(grid_t), intent(in) :: grid
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    type(image_t) :: img
    integer(int8), allocatable :: image_mat(:, :)
    integer(i8) :: c, nc, g, n
    integer(i8), allocatable :: hits(:)
    integer :: i, j, k, m, ierr
    real(wp) :: xc, yc

    call this%free()
    stat = 0
    msg = ''
    this%grid = grid
    this%n_materials = size(cfg%materials)
    this%background = cfg%geometry%background_id
    allocate(this%shapes(size(cfg%shapes)))
    do k = 1, size(cfg%shapes)
      associate(s => cfg%shapes(k))
        select case (trim(s%kind))
        case ('rectangle')
          this%shapes(k) = shape_rectangle(s%box(1), s%box(2), s%box(3), s%box(4), s%material_id)
        case ('circle')
          this%shapes(k) = shape_circle(s%center(1), s%center(2), s%radius, s%material_id)
        case default
          this%shapes(k) = shape_polygon(s%points, s%material_id)
        end select
      end associate
    end do
    this%uniform = size(this%shapes) == 0 .and. len_trim(cfg%geometry%image) == 0
    nc = grid%n_cells
    allocate(this%material_cells(this%n_materials))
    this%material_cells = 0
    if (this%uniform) then
      if (this%background == 0) then
        stat = 1
        msg = "&geometry: background = 'void' with no image and no &shape: the body is empty"
        return
      end if
      this%n_cells = nc
      this%n_nodes = grid%n_nodes
      this%material_cells(this%background) = nc
      this%n_pieces = 1
      return
    end if

    ! the image cell map, if any: pixel (column c, row r) is cell (c - 1, ny - r)
    if (len_trim(cfg%geometry%image) > 0) then
      call read_image(trim(cfg%geometry%image), img, stat, msg)
      if (stat /= 0) then
        msg = '&geometry: image = '''//trim(cfg%geometry%image)//''': '//msg
        return
      end if
      if (img%width /= grid%nx .or. img%height /= grid%ny) then
        stat = 1
        msg = '&geometry: image = '''//trim(cfg%geometry%image)//''' is '//itoa(img%width)// &
              ' x '//itoa(img%height)//' pixels but the grid has nx, ny = '//itoa(grid%nx)// &
              ', '//itoa(grid%ny)//' cells (one pixel a cell)'
        return
      end if
      allocate(image_mat(grid%nx, grid%ny), stat=ierr)
      if (ierr /= 0) then
        call no_memory('the image cell map')
        return
      end if
      do j = 1, grid%ny
        do i = 1, grid%nx
          k = findloc(cfg%geometry%image_levels, img%pix(i, grid%ny - j + 1), 1)
          if (k == 0) then
            stat = 1
            msg = '&geometry: image = '''//trim(cfg%geometry%image)//''': pixel (column '// &
                  itoa(i)//', row '//itoa(grid%ny - j + 1)//') has the grey level '// &
                  itoa(img%pix(i, grid%ny - j + 1))//', which is not in image_levels'
            return
          end if
          image_mat(i, j) = int(cfg%geometry%image_material_ids(k), int8)
        end do
      end do
      deallocate(img%pix)
    end if

    allocate(this%cell_mat(0:nc - 1), this%cell_src(0:nc - 1), this%cell_id(0:nc - 1), &
             this%node_id(0:grid%n_nodes - 1), hits(size(this%shapes)), stat=ierr)
    if (ierr /= 0) then
      call no_memory('the cell map of the body')
      return
    end if
    hits = 0
    n = 0
    do j = 0, grid%ny - 1
      do i = 0, grid%nx - 1
        c = int(i, i8) + int(j, i8)*grid%nx
        m = this%background
        if (allocated(image_mat)) m = image_mat(i + 1, j + 1)
        this%cell_src(c) = 0
        xc = (i + 0.5_wp)*grid%lx
        yc = (j + 0.5_wp)*grid%ly
        do k = 1, size(this%shapes)
          if (shape_contains(this%shapes(k), xc, yc)) then
            hits(k) = hits(k) + 1
            m = this%shapes(k)%material
            this%cell_src(c) = int(k, int8)
          end if
        end do
        this%cell_mat(c) = int(m, int8)
        if (m > 0) then
          this%cell_id(c) = n
          n = n + 1
          this%material_cells(m) = this%material_cells(m) + 1
        else
          this%cell_id(c) = -1
        end if
      end do
    end do
    this%n_cells = n
    do k = 1, size(this%shapes)
      if (hits(k) == 0) then
        stat = 1
        msg = '&shape #'//itoa(k)//" ('"//trim(cfg%shapes(k)%name)//"'): holds no cell "// &
              'centre of the grid [0, '//rtoa(grid%nx*grid%lx)//'] x [0, '// &
              rtoa(grid%ny*grid%ly)//'] (outside it, or smaller than a cell of '// &
              rtoa(grid%lx)//' x '//rtoa(grid%ly)//' m)'
        return
      end if
    end do
    if (this%n_cells == 0) then
      stat = 1
      msg = '&geometry: the body is empty: no cell of the '//itoa(grid%nx)//' x '// &
            itoa(grid%ny)//' grid has a material (background, image and &shape groups)'
      return
    end if
    do k = 1, this%n_materials
      if (this%material_cells(k) == 0) then
        stat = 1
        msg = '&material #'//itoa(k)//" ('"//trim(cfg%materials(k)%name)//"'): no cell of "// &
              'the body is of this material; remove it or give it to a &shape'
        return
      end if
    end do
    ! nodes: those of the cells of the body, numbered row by row
    n = 0
    do j = 0, grid%ny
      do i = 0, grid%nx
        g = grid%node_id(i, j)
        if (node_used(this, i, j)) then
          this%node_id(g) = n
          n = n + 1
        else
          this%node_id(g) = -1
        end if
      end do
    end do
    this%n_nodes = n
    allocate(this%cell_grid(0:this%n_cells - 1), this%node_grid(0:this%n_nodes - 1), stat=ierr)
    if (ierr /= 0) then
      call no_memory('the numbering of the body')
      return
    end if
    do c = 0, nc - 1
      if (this%cell_id(c) >= 0) this%cell_grid(this%cell_id(c)) = c
    end do
    do g = 0, grid%n_nodes - 1
      if (this%node_id(g) >= 0) this%node_grid(this%node_id(g)) = g
    end do
    call count_pieces(this)

  contains

    subroutine no_memory(what)
      character(len=*), intent(in) :: what
      stat = 1
      msg = grid%label()//': out of memory allocating '//what
    end subroutine no_memory
  end subroutine body_init

  !> Whether grid node (i, j) is used by a cell of the body (not uniform bodies).
  pure logical function node_used(this, i, j)
    type(body_t), intent(in) :: this
    integer, intent(in) :: i, j
    integer :: di, dj
    node_used = .false.
    do dj = -1, 0
      do di = -1, 0
        if (this%material(i + di, j + dj) > 0) node_used = .true.
      end do
    end do
  end function node_used

  !> Count the pieces of the body: cells joined when they share a node (union-find).
  subroutine count_pieces(this)
    type(body_t), intent(inout) :: this
    integer(i8), allocatable :: parent(:), size_of(:)
    integer(i8) :: c, r, big
    integer :: i, j, di, dj, ij(2), ierr, k
    allocate(parent(0:this%n_cells - 1), stat=ierr)
    if (ierr /= 0) then
      this%n_pieces = 1
      return
    end if
    do c = 0, this%n_cells - 1
      parent(c) = c
    end do
    do c = 0, this%n_cells - 1
      ij = this%cell_ij(c)
      do dj = -1, 1
        do di = -1, 1
          i = ij(1) + di
          j = ij(2) + dj
          r = this%cell_number(i, j)
          if (r >= 0) call join(c, r)
        end do
      end do
    end do
    this%n_pieces = 0
    allocate(size_of(0:this%n_cells - 1), source=0_i8)
    do c = 0, this%n_cells - 1
      r = root(c)
      if (r == c) this%n_pieces = this%n_pieces + 1
      size_of(r) = size_of(r) + 1
    end do
    ! a cell of each piece but the largest, for the log
    big = maxloc(size_of, 1) - 1
    k = 0
    do c = 0, this%n_cells - 1
      if (parent(c) == c .and. c /= big .and. k < size(this%piece_cell)) then
        k = k + 1
        this%piece_cell(k) = c
      end if
    end do
  contains
    integer(i8) function root(a) result(r_)
      integer(i8), intent(in) :: a
      r_ = a
      do while (parent(r_) /= r_)
        parent(r_) = parent(parent(r_))
        r_ = parent(r_)
      end do
    end function root
    subroutine join(a, b)
      integer(i8), intent(in) :: a, b
      integer(i8) :: ra, rb
      ra = root(a)
      rb = root(b)
      if (ra /= rb) parent(max(ra, rb)) = min(ra, rb)
    end subroutine join
  end subroutine count_pieces

  !> Material (0: void or outside the grid) of grid cell (i, j).
  pure integer function body_material(this, i, j) result(m)
    class(body_t), intent(in) :: this
    integer, intent(in) :: i, j
    m = 0
    if (i < 0 .or. j < 0 .or. i >= this%grid%nx .or. j >= this%grid%ny) return
    if (this%uniform) then
      m = this%background
    else
      m = this%cell_mat(int(i, i8) + int(j, i8)*this%grid%nx)
    end if
  end function body_material

  !> The shape that decided grid cell (i, j) (0: the background or the image; -1: outside
  !> the grid).
  pure integer function body_source(this, i, j) result(k)
    class(body_t), intent(in) :: this
    integer, intent(in) :: i, j
    k = -1
    if (i < 0 .or. j < 0 .or. i >= this%grid%nx .or. j >= this%grid%ny) return
    k = 0
    if (.not. this%uniform) k = this%cell_src(int(i, i8) + int(j, i8)*this%grid%nx)
  end function body_source

  !> Number (0-based) of grid cell (i, j) in the body; -1 when it is not in the body.
  pure integer(i8) function body_cell_number(this, i, j) result(c)
    class(body_t), intent(in) :: this
    integer, intent(in) :: i, j
    c = -1
    if (i < 0 .or. j < 0 .or. i >= this%grid%nx .or. j >= this%grid%ny) return
    c = int(i, i8) + int(j, i8)*this%grid%nx
    if (.not. this%uniform) c = this%cell_id(c)
  end function body_cell_number

  !> Number (0-based) of grid node (i, j) in the body; -1 when no cell of the body uses it.
  pure integer(i8) function body_node_number(this, i, j) result(g)
    class(body_t), intent(in) :: this
    integer, intent(in) :: i, j
    g = -1
    if (i < 0 .or. j < 0 .or. i > this%grid%nx .or. j > this%grid%ny) return
    g = this%grid%node_id(i, j)
    if (.not. this%uniform) g = this%node_id(g)
  end function body_node_number

  !> Grid indices (i, j) of node g of the body.
  pure function body_node_ij(this, g) result(ij)
    class(body_t), intent(in) :: this
    integer(i8), intent(in) :: g
    integer :: ij(2)
    if (this%uniform) then
      ij = this%grid%node_ij(g)
    else
      ij = this%grid%node_ij(this%node_grid(g))
    end if
  end function body_node_ij

  !> Grid indices (i, j) of cell c of the body.
  pure function body_cell_ij(this, c) result(ij)
    class(body_t), intent(in) :: this
    integer(i8), intent(in) :: c
    integer :: ij(2)
    integer(i8) :: q
    q = c
    if (.not. this%uniform) q = this%cell_grid(c)
    ij(1) = int(mod(q, int(this%grid%nx, i8)))
    ij(2) = int(q/int(this%grid%nx, i8))
  end function body_cell_ij

  !> Reference coordinates of node g of the body.
  pure function body_node_xy(this, g) result(xy)
    class(body_t), intent(in) :: this
    integer(i8), intent(in) :: g
    real(wp) :: xy(2)
    integer :: ij(2)
    ij = this%node_ij(g)
    xy = [ij(1)*this%grid%lx, ij(2)*this%grid%ly]
  end function body_node_xy

  !> The node of the body nearest to (x, y): the nearest grid node when the body uses it,
  !> else the nearest node of the body (ties: the lowest number).
  pure integer(i8) function body_nearest_node(this, x, y) result(best)
    class(body_t), intent(in) :: this
    real(wp), intent(in) :: x, y
    integer(i8) :: g
    integer :: i0, j0, i, j, r
    real(wp) :: d, dbest
    g = this%grid%nearest_node(x, y)
    best = this%node_number(int(mod(g, int(this%grid%nx + 1, i8))), &
                            int(g/int(this%grid%nx + 1, i8)))
    if (best >= 0) return
    ! search rings of growing radius around the grid node until a found node cannot be beaten
    i0 = int(mod(g, int(this%grid%nx + 1, i8)))
    j0 = int(g/int(this%grid%nx + 1, i8))
    dbest = huge(1.0_wp)
    do r = 1, max(this%grid%nx, this%grid%ny) + 1
      do j = j0 - r, j0 + r
        do i = i0 - r, i0 + r
          if (max(abs(i - i0), abs(j - j0)) /= r) cycle
          g = this%node_number(i, j)
          if (g < 0) cycle
          d = (i*this%grid%lx - x)**2 + (j*this%grid%ly - y)**2
          if (d < dbest .or. (d == dbest .and. g < best)) then
            dbest = d
            best = g
          end if
        end do
      end do
      ! nodes of later rings are at least (r - 1) cells further than the grid node
      if (best >= 0 .and. sqrt(dbest) < (r - 1)*min(this%grid%lx, this%grid%ly)) exit
    end do
  end function body_nearest_node

  !> The cell of the body that holds (x, y) (points on the far sides of the grid belong to
  !> the last cells); -1 when that cell is not in the body.
  pure integer(i8) function body_cell_at(this, x, y) result(c)
    class(body_t), intent(in) :: this
    real(wp), intent(in) :: x, y
    integer :: i, j
    i = min(max(int(x/this%grid%lx), 0), this%grid%nx - 1)
    j = min(max(int(y/this%grid%ly), 0), this%grid%ny - 1)
    c = this%cell_number(i, j)
  end function body_cell_at

  !> Numbers of the corner nodes of cell c of the body, counter-clockwise from lower left.
  pure function body_cell_corners(this, c) result(nodes)
    class(body_t), intent(in) :: this
    integer(i8), intent(in) :: c
    integer(i8) :: nodes(4)
    integer :: ij(2)
    ij = this%cell_ij(c)
    nodes(1) = this%node_number(ij(1), ij(2))
    nodes(2) = this%node_number(ij(1) + 1, ij(2))
    nodes(3) = this%node_number(ij(1) + 1, ij(2) + 1)
    nodes(4) = this%node_number(ij(1), ij(2) + 1)
  end function body_cell_corners

  !> Release the maps.
  subroutine body_free(this)
    class(body_t), intent(inout) :: this
    if (allocated(this%shapes)) deallocate(this%shapes)
    if (allocated(this%cell_mat)) deallocate(this%cell_mat)
    if (allocated(this%cell_src)) deallocate(this%cell_src)
    if (allocated(this%cell_id)) deallocate(this%cell_id)
    if (allocated(this%node_id)) deallocate(this%node_id)
    if (allocated(this%cell_grid)) deallocate(this%cell_grid)
    if (allocated(this%node_grid)) deallocate(this%node_grid)
    if (allocated(this%material_cells)) deallocate(this%material_cells)
    this%uniform = .true.
    this%n_nodes = 0
    this%n_cells = 0
  end subroutine body_free
end module iem_body
